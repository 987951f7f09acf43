// VTU snapshots of a distributed run written by all its processes into one file: each writes
// the values of the nodes and bars it owns at their places in the file (io/output.hpp's
// VtuLayout), so the file is byte for byte the one a single process writes and no process
// gathers the body.
#pragma once

#include "io/output.hpp"
#include "parallel/subdomain.hpp"

#include <string>
#include <vector>

namespace ldem {

class SubdomainVtuWriter {
public:
  // `whole` is the body's lattice; run.sim()'s table says whether the material fields vary.
  // `arrays`: the optional arrays to write (vtu_array_names; empty: all).
  SubdomainVtuWriter(const SubdomainRun& run, const Lattice& whole,
                     const std::vector<std::string>& arrays = {});
  // The snapshot of the current state at `path`. Collective.
  void write(const SubdomainRun& run, const std::string& path);

private:
  Lattice whole_;
  PresentRanks ranks_; // a shaped body's: its snapshots hold the present nodes and bars only
  VtuLayout layout_;
  std::vector<Span> nodes_, bars_; // owned
  std::vector<char> buf_;          // one span's values, reused
  std::vector<index_t> picks_;     // the span's items the file holds
  std::vector<std::uint8_t> state_;
  std::vector<double> damage_, force_, strain_;
  std::vector<Vec3> u_, v_;       // one span's node states, reused
  std::vector<double> law_state_; // one span's values of a law's state array, reused
};

} // namespace ldem
