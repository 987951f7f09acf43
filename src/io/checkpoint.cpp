#include "io/checkpoint.hpp"

#include <fmt/format.h>
#include <fstream>

namespace ldem::checkpoint {

std::string get_str(const std::string& in, std::size_t& pos) {
  std::uint64_t n = 0;
  get(in, pos, n);
  if (pos + n > in.size())
    throw InputError("checkpoint: truncated");
  std::string s = in.substr(pos, n);
  pos += n;
  return s;
}

std::uint64_t fnv1a(const char* p, std::size_t n) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < n; ++i)
    h = (h ^ static_cast<unsigned char>(p[i])) * 0x100000001b3ull;
  return h;
}

namespace {
std::uint64_t mix(std::uint64_t z) { // splitmix64's finaliser
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
} // namespace

std::uint64_t word_hash(std::uint64_t place, double value) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  return mix(bits ^ mix(place + 0x9E3779B97F4A7C15ull));
}

std::string header_bytes(const std::string& meta, const std::string& progress,
                         std::uint64_t checksum) {
  std::string out(kMagic, 8);
  put(out, kVersion);
  put(out, static_cast<std::uint64_t>(meta.size()));
  put(out, static_cast<std::uint64_t>(progress.size()));
  put(out, checksum);
  return out;
}

Header read_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in)
    throw InputError(fmt::format("{}: no checkpoint to resume from", path));
  Header h;
  h.file_bytes = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  std::string head(kHeaderBytes, '\0');
  if (h.file_bytes < kHeaderBytes || !in.read(head.data(), kHeaderBytes) ||
      head.compare(0, 8, std::string(kMagic, 8)) != 0)
    throw InputError(fmt::format("{}: not an ldem checkpoint (or truncated)", path));
  std::size_t p = 8;
  std::uint32_t version = 0;
  std::uint64_t meta = 0, progress = 0;
  get(head, p, version);
  if (version != kVersion)
    throw InputError(fmt::format("{}: checkpoint format version {}, this ldem reads version {}",
                                 path, version, kVersion));
  get(head, p, meta);
  get(head, p, progress);
  get(head, p, h.checksum);
  if (h.file_bytes < Header::arrays_offset(meta, progress))
    throw InputError(fmt::format("{}: truncated checkpoint ({} bytes, its header says at least "
                                 "{})",
                                 path, h.file_bytes, Header::arrays_offset(meta, progress)));
  h.meta.resize(meta);
  h.progress.resize(progress);
  if (!in.read(h.meta.data(), static_cast<std::streamsize>(meta)) ||
      !in.read(h.progress.data(), static_cast<std::streamsize>(progress)))
    throw InputError(fmt::format("{}: cannot read the checkpoint", path));
  return h;
}

} // namespace ldem::checkpoint
