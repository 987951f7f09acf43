// The checkpoint file of a run, DIR/checkpoint/state.ckpt:
//
//   magic "LDEMCKPT", format version (u32), meta bytes (u64), progress bytes (u64), checksum
//   (u64), the meta (the run's state: its case, where its outputs stand), the progress (the
//   body's step, dt, energy ledger, last report, events not yet written), zeros up to a
//   multiple of 8 bytes, then arrays of doubles in the body's order: ux, uy, uz (u_n) and wx,
//   wy, wz (u_{n-1}) per node, h per bar.
//
// The checksum is FNV-1a of meta and progress plus, modulo 2^64, a hash of every array word
// with its place: it adds over the pieces of the arrays, so that the processes of a run write
// and check their parts each and the file is the same whoever wrote it.
#pragma once

#include "util/error.hpp"

#include <cstdint>
#include <cstring>
#include <string>

namespace ldem::checkpoint {

inline constexpr char kMagic[8] = {'L', 'D', 'E', 'M', 'C', 'K', 'P', 'T'};
inline constexpr std::uint32_t kVersion = 3;
inline constexpr std::uint64_t kHeaderBytes = 8 + 4 + 3 * 8;

template <class T> void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
inline void put_str(std::string& out, const std::string& s) {
  put(out, static_cast<std::uint64_t>(s.size()));
  out += s;
}
template <class T> void get(const std::string& in, std::size_t& pos, T& v) {
  if (pos + sizeof v > in.size())
    throw InputError("checkpoint: truncated");
  std::memcpy(&v, in.data() + pos, sizeof v);
  pos += sizeof v;
}
std::string get_str(const std::string& in, std::size_t& pos);

std::uint64_t fnv1a(const char* p, std::size_t n);
// The checksum's term of the array word at `place` (counted in doubles from the arrays' start).
std::uint64_t word_hash(std::uint64_t place, double value);

struct Header {
  std::string meta, progress;
  std::uint64_t checksum = 0;
  std::uint64_t file_bytes = 0;
  // Where the arrays start.
  std::uint64_t arrays_at() const { return arrays_offset(meta.size(), progress.size()); }
  static std::uint64_t arrays_offset(std::uint64_t meta, std::uint64_t progress) {
    return (kHeaderBytes + meta + progress + 7) / 8 * 8;
  }
};

// The header, meta and progress of the checkpoint at `path`. Throws InputError when there is
// none, the file is not a checkpoint, of another format version, or shorter than its header
// says.
Header read_header(const std::string& path);

// The header bytes (magic to checksum) of a checkpoint with this meta and progress.
std::string header_bytes(const std::string& meta, const std::string& progress,
                         std::uint64_t checksum);

} // namespace ldem::checkpoint
