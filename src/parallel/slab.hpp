// Slab decomposition of a lattice along z, for runs spread over several processes.
//
// Rank p of P owns the modules [m0, m1) along z (m0 = p nz / P) with their corner planes
// [m0, m1) (the last rank also corner plane nz) and centre planes [m0, m1). It steps a local
// lattice over the window of modules [w0, w1) = [m0 - 1, m1 + 1), clipped to the body: its own
// modules and one ghost module on each side. Every bar that touches an owned node lies in
// that window, and an owned node has the same neighbourhood (modules around it, hence lumped
// mass and bar area factors) as in the whole body, so its force, and thus its motion, is the
// same number as in a single-process run. Ghost nodes are held by the local run and receive
// their displacements from the neighbouring rank after every step:
//   from below: corner and centre planes m0 - 1;  from above: corner and centre planes m1.
// Bar plane k (block index k) is owned by the rank that owns module k (corner plane nz's
// in-plane bars by the last rank): each bar's history and events have one owner, and the
// ghost module below evolves the same histories bit for bit from the same displacements.
#pragma once

#include "lattice/lattice.hpp"
#include "solver/simulation.hpp"

#include <vector>

namespace ldem {

struct Slab {
  int rank = 0, ranks = 1;
  index_t nz = 0;         // modules of the body along z
  index_t m0 = 0, m1 = 0; // owned modules
  index_t w0 = 0, w1 = 0; // local window of modules
  bool below() const { return rank > 0; }
  bool above() const { return rank + 1 < ranks; }
  index_t local_nz() const { return w1 - w0; }
  // Whether the slab owns plane k of the body: its centre plane or bar plane k (corner = false
  // for a centre plane; bar planes count as corner planes), or its corner plane k.
  bool owns_plane(index_t k, bool corner) const {
    return (k >= m0 && k < m1) || (corner && k == nz && !above());
  }
};

// Throws InputError when the body has fewer modules along z than there are ranks.
Slab make_slab(index_t nz, int ranks, int rank);

// A run of consecutive node or bar numbers of the slab's window lattice and the same run in
// the body's lattice.
struct Span {
  index_t local_first, global_first, count;
};
// The nodes of the window (corner planes, then centre planes), or with `owned` those the
// slab owns; and the window's bars (family by family, a span of k-planes each), or those it
// owns. Owned spans of the slabs of all ranks cover the body once.
std::vector<Span> slab_node_spans(const Slab& slab, const Lattice& whole, bool owned);
std::vector<Span> slab_bar_spans(const Slab& slab, const Lattice& whole, bool owned);
// The window's lattice of a slab of `whole`.
Lattice window_lattice(const Slab& slab, const Lattice& whole);
// The body's number of a bar of the window's lattice `local`.
index_t global_bar(const Slab& slab, const Lattice& local, const Lattice& whole, index_t bar);

// The whole body's conditions restricted to the nodes the slab owns, in the numbers of its
// window's lattice `local` (the order of each set kept); a condition on none of them is left
// out. Ghost nodes are not included: their owner applies the condition and sends them.
Conditions slab_conditions(const Slab& slab, const Lattice& whole, const Lattice& local,
                           const Conditions& conditions);

// The local run of one slab: a Simulation over the window, its ghost nodes held, and the
// planes it exchanges with its neighbours.
class SlabRun {
public:
  // `local` is the window's lattice (nx, ny, slab.local_nz()); `conditions` refer to its
  // nodes, `precracked` to its bars (sorted). The ghost planes are added as held nodes.
  SlabRun(const Slab& slab, Lattice local, BarTable table, Conditions conditions,
          SolverOptions options, std::vector<index_t> precracked = {});

  const Slab& slab() const { return slab_; }
  Simulation& sim() { return sim_; }
  const Simulation& sim() const { return sim_; }

  // Local node number of the global node (i, j, k) of the body (corner or centre), and the
  // inverse; global_node is only valid for nodes inside the window.
  index_t local_node(const NodeAddress& global) const;
  NodeAddress global_address(index_t local) const;
  // Whether this rank owns the local node (integrates it and reports it).
  bool owns(index_t local) const;

  // The rows of the last report's energies that this slab owns (its bar planes, its node
  // planes), appended in the whole body's row order: elastic and dissipated energy per bar
  // row, kinetic energy per node row. Slab after slab, in rank order, they are the whole
  // body's rows, so summed in that order they give its energies bit for bit.
  void append_owned_energy_rows(std::vector<double>& elastic, std::vector<double>& damage,
                                std::vector<double>& kinetic) const;

  // Halo exchange: the doubles to send to the rank below (dir = -1) or above (+1), and the
  // doubles received from it. Both sides agree on the sizes (halo_size).
  std::size_t halo_size(int dir) const;
  void pack(int dir, std::vector<double>& out) const;
  void unpack(int dir, const std::vector<double>& in);

private:
  // Local corner and centre plane numbers sent towards dir, and received from it.
  index_t send_plane(int dir) const;
  index_t recv_plane(int dir) const;

  Slab slab_;
  Simulation sim_;
};

} // namespace ldem
