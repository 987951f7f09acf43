#include "util/text_file.hpp"

#include "util/error.hpp"

#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <sstream>

namespace ldem {

std::string read_text_file(const std::string& path, const std::string& what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st))
    throw InputError(fmt::format("{}: cannot read {} (missing or not readable)", path, what));
  if (!fs::is_regular_file(st))
    throw InputError(fmt::format("{}: expected {} as a regular file; got {}", path, what,
                                 fs::is_directory(st)   ? "a directory"
                                 : fs::is_character_file(st) || fs::is_block_file(st)
                                     ? "a device"
                                 : fs::is_fifo(st) ? "a pipe"
                                                   : "a special file"));
  const std::uintmax_t size = fs::file_size(path, ec);
  if (!ec && size > kMaxTextFile)
    throw InputError(fmt::format("{}: expected {} of at most {} MiB; got {:.1f} MiB", path, what,
                                 kMaxTextFile >> 20, static_cast<double>(size) / (1 << 20)));
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(fmt::format("{}: cannot read {} (missing or not readable)", path, what));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

} // namespace ldem
