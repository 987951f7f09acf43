// libFuzzer target: any bytes given to the case-file reader either parse or raise InputError;
// nothing else (no crash, no other exception, no sanitizer report).
#include "io/case_spec.hpp"
#include "util/error.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    ldem::parse_case(std::string(reinterpret_cast<const char*>(data), size), "fuzz.toml");
  } catch (const ldem::InputError&) {
  }
  return 0;
}
