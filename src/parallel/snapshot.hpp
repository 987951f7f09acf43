// VTU snapshots of a distributed run written by all its processes into one file: each writes
// the values of the nodes and bars it owns at their places in the file (io/output.hpp's
// VtuLayout), so the file is byte for byte the one a single process writes and no process
// gathers the body. Compressed snapshots take one more pass: every array's bytes go, block by
// block, to the process that compresses those blocks (each process a share of consecutive
// blocks), whose compressed sizes then place every block in the file.
#pragma once

#include "io/output.hpp"
#include "parallel/subdomain.hpp"

#include <map>
#include <string>
#include <vector>

namespace ldem {

class SubdomainVtuWriter {
public:
  // `whole` is the body's lattice; run.sim()'s table says whether the material fields vary.
  // `arrays`: the optional arrays to write (vtu_array_names; empty: all); `zlib`: compressed.
  SubdomainVtuWriter(const SubdomainRun& run, const Lattice& whole,
                     const std::vector<std::string>& arrays = {}, bool zlib = false);
  // The snapshot of the current state at `path`. Collective.
  void write(const SubdomainRun& run, const std::string& path);

private:
  // One array's share of a compressed snapshot on this process: its blocks [first, first +
  // mine.size()) compressed, and every block's compressed size (all processes').
  struct ZlibShare {
    std::uint64_t bytes = 0; // the array's, uncompressed
    std::vector<std::uint64_t> sizes;
    std::uint64_t first = 0;
    std::string mine;
    std::uint64_t stored() const; // the array's bytes in the file, its block header included
  };
  // A piece of an array on this process: its position in the array's bytes, and the bytes.
  struct Piece {
    std::uint64_t at;
    std::string bytes;
  };
  // The share of the array of `bytes` bytes whose pieces the processes hold. Collective.
  static ZlibShare compress(const std::vector<Piece>& pieces, std::uint64_t bytes);
  // The stress or strain (6 per window node) at the owned nodes, from the owned modules' and
  // the neighbours' ghost modules'. Collective.
  void node_tensors(const SubdomainRun& run, bool stress);
  void write_compressed(const SubdomainRun& run, const std::string& path);

  Lattice whole_;
  PresentRanks ranks_; // a shaped body's: its snapshots hold the present nodes and bars only
  VtuLayout layout_;
  std::vector<std::string> arrays_;
  bool zlib_ = false;
  std::vector<Span> nodes_, bars_; // owned
  std::vector<char> buf_;          // one span's values, reused
  std::vector<index_t> picks_;     // the span's items the file holds
  std::vector<std::uint8_t> state_;
  std::vector<double> damage_, force_, strain_;
  std::vector<Vec3> u_, v_;       // one span's node states, reused
  std::vector<double> law_state_; // one span's values of a law's state array, reused
  // Stress and strain: every window node's displacement, the modules' tensors, the nodes'.
  std::vector<Vec3> u_all_, v_all_;
  std::vector<double> module_, stress_, node_strain_, halo_values_, halo_[4];
  // Compressed: this snapshot's pieces by key (VtuLayout::Array, or kArrays + q for the law's
  // q-th state array), and the shares, the arrays that do not change kept from the first.
  std::map<int, std::vector<Piece>> pieces_;
  std::map<int, ZlibShare> shares_;
};

} // namespace ldem
