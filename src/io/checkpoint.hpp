// The checkpoint file of a run, DIR/checkpoint/state.ckpt:
//
//   magic "LDEMCKPT", format version (u32), meta bytes (u64), progress bytes (u64), checksum
//   (u64), the meta (the run's state: its case, where its outputs stand), the progress (the
//   body's step, dt, energy ledger, last report, node and bar counts, its bar law, the list of
//   arrays that follow by name, and the events not yet written), zeros up to a multiple of 8
//   bytes, then the arrays of doubles in that list's order, each in the body's order: per node
//   u_n and u_{n-1} along x, y and z, per bar the bar law's state arrays (Simulation::
//   state_arrays). A law's state is thus saved and restored by name, whatever the law.
//
// The checksum is FNV-1a of meta and progress plus, modulo 2^64, a hash of every array word
// with its place: it adds over the pieces of the arrays, so that the processes of a run write
// and check their parts each and the file is the same whoever wrote it.
#pragma once

#include "energy/ledger.hpp"
#include "solver/simulation.hpp"
#include "util/error.hpp"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace ldem::checkpoint {

inline constexpr char kMagic[8] = {'L', 'D', 'E', 'M', 'C', 'K', 'P', 'T'};
// 7: the run's end and output intervals in its meta; 8: platens (their friction in the ledger,
// their places in the progress, the contact energy in the report)
inline constexpr std::uint32_t kVersion = 8;
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

inline constexpr std::uint64_t kFnvStart = 0xcbf29ce484222325ull;
// FNV-1a of n bytes, continuing from the hash `h` of the bytes before them.
std::uint64_t fnv1a(const char* p, std::size_t n, std::uint64_t h = kFnvStart);
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

// Where the body stands: what a checkpoint holds besides its meta and its arrays' values.
struct Progress {
  std::uint64_t step = 0;
  double dt = 0.0;
  Ledger::State ledger;
  EnergyReport report{};
  std::uint64_t nodes = 0, bars = 0;
  std::string law; // the bar law's name
  std::vector<Simulation::NamedArray> arrays;
  std::vector<Event> events; // not yet written
  std::vector<double> platens; // Simulation::platen_positions
  // Where array a starts, in doubles from the arrays' start, and the doubles of all arrays.
  std::uint64_t array_place(std::size_t a) const;
  std::uint64_t array_doubles() const { return array_place(arrays.size()); }
};
std::string progress_bytes(const Progress& p);
// The progress of the checkpoint at `path` (its header h). Throws InputError naming the file
// when the progress is truncated.
Progress read_progress(const Header& h, const std::string& path);
// Throws InputError naming `path` unless the checkpoint `file` (header h) can resume the body
// `body` (this case's counts, dt, bar law, arrays and platens; `file` read by read_progress): a
// body of other node or bar counts, another time step, another bar law, other state arrays or
// another number of platens, or a file whose length is not that of its arrays.
void check_resumes(const Progress& file, const Header& h, const Progress& body,
                   const std::string& path);

} // namespace ldem::checkpoint
