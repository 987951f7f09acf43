// Decomposition of a lattice into boxes of modules over y and z, for runs spread over several
// processes.
//
// The P processes form a grid of Py x Pz boxes (rank = cy + Py cz). Along a split axis of n
// modules (y: index j, z: index k), the process at coordinate c of C owns the modules
// [m0, m1) (m0 = c n / C) with their corner rows or planes [m0, m1) (the last along the axis
// also corner n) and centre rows or planes [m0, m1). Rows of nodes along x are never split:
// every process steps whole rows, so its gather and bar kernel take the same path per row as
// one process does.
//
// A process steps a local lattice over the window of modules [w0, w1) = [m0 - 1, m1 + 1) along
// each split axis, clipped to the body: its own modules and one ghost module on each side.
// Every bar that touches an owned node lies in that window, and an owned node has the same
// neighbourhood (modules around it, hence lumped mass and bar area factors) as in the whole
// body, so its force, and thus its motion, is the same number as in a single-process run.
// Ghost nodes are held by the local run and receive their displacements from the neighbours
// after every step, in two phases: along y the owned planes' rows m0 and m1 - 1 (corner and
// centre), then along z whole window planes m0 and m1 - 1, which carry the ghost rows just
// received, so the diagonal neighbours' nodes arrive too. The window's outermost corner row
// and plane (index w1 where a neighbour lies above) are held and never sent: no bar of an
// owned node reaches them.
// A bar (f, i, j, k) belongs to the process that owns its first node, i.e. module (j, k) (the
// last along an axis also index n): each bar's history and events have one owner, and the ghost
// modules evolve the same histories bit for bit from the same displacements.
#pragma once

#include "lattice/lattice.hpp"
#include "solver/simulation.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ldem {

// One process's share of one axis of modules.
struct AxisPart {
  index_t n = 0;            // modules of the body along the axis
  int coord = 0, parts = 1; // this process's place along the axis, and the processes on it
  index_t m0 = 0, m1 = 0;   // owned modules
  index_t w0 = 0, w1 = 0;   // window of modules
  std::vector<index_t>
      firsts; // every part's first module, and n: part p owns [firsts[p], firsts[p + 1])
  bool below() const { return coord > 0; }
  bool above() const { return coord + 1 < parts; }
  index_t local_n() const { return w1 - w0; }
  // Whether index idx along the axis is owned: of a centre row or plane (corner = false), or
  // of a corner one or a bar's block (corner = true).
  bool owns(index_t idx, bool corner) const {
    return (idx >= m0 && idx < m1) || (corner && idx == n && !above());
  }
  // The end of the owned corner (or bar block) indices: m1, or n + 1 on the last part.
  index_t corner_end() const { return above() ? m1 : n + 1; }
};

// Splits n modules into `parts` along an axis; `coord` is the process's place. Without
// weights the parts hold n / parts modules each (give or take one); with weights (one per layer
// of modules along the axis: a shaped body's present modules) the cuts balance their sums,
// every part keeping at least one layer.
AxisPart split_axis(index_t n, int parts, int coord,
                    const std::vector<std::uint64_t>* weights = nullptr);

// The grid of processes: Py boxes along y times Pz along z.
struct ProcessGrid {
  int py = 1, pz = 1;
  bool operator==(const ProcessGrid&) const = default;
};
// The grid for `ranks` processes on a body of ny x nz modules across x: of the grids with at
// least one module per box along each axis, the one that cuts the least area (fewest modules
// on the cut faces, (Py - 1) nz + (Pz - 1) ny), slabs along z on a tie. Throws InputError
// (the case key, the sizes, what would fit) when none fits.
ProcessGrid choose_grid(index_t ny, index_t nz, int ranks);
// The grid a user asked for (--process-grid PY PZ), checked against the process count and the
// body (InputError naming the option), or choose_grid's when `asked` is {0, 0}.
ProcessGrid resolve_grid(index_t ny, index_t nz, int ranks, ProcessGrid asked);

struct Subdomain {
  int rank = 0, ranks = 1;
  ProcessGrid grid;
  AxisPart y, z;
  // Whether the subdomain owns node (j, k) of the body (corner = false for a centre), or bar
  // block (j, k) (corner = true).
  bool owns(index_t j, index_t k, bool corner) const {
    return y.owns(j, corner) && z.owns(k, corner);
  }
  // The rank of the neighbour one step along axis 1 (y) or 2 (z) towards dir (-1 or +1), or
  // -1 where there is none.
  int neighbour(int axis, int dir) const;
};

// Rank `rank` of `ranks` on a body of ny x nz modules across x, on choose_grid's grid or on a
// given one (grid.py grid.pz == ranks, each axis at least one module per box).
Subdomain make_subdomain(index_t ny, index_t nz, int ranks, int rank);
Subdomain make_subdomain(index_t ny, index_t nz, ProcessGrid grid, int rank);
// The same for a body: a shaped body's cuts balance its present modules along y and along z.
Subdomain make_subdomain(const Lattice& whole, ProcessGrid grid, int rank);
// How the processes of `grid` share the body, for the run's log: the grid and the boxes' sizes.
std::string describe_decomposition(const Lattice& whole, ProcessGrid grid);
// The rank that owns node or bar block (j, k) of the body.
int owner_rank(const Subdomain& any, index_t j, index_t k);

// A run of consecutive node or bar numbers of the subdomain's window lattice and the same run
// in the body's lattice.
struct Span {
  index_t local_first, global_first, count;
};
// The nodes of the window (corner planes, then centre planes), or with `owned` those the
// subdomain owns; and the window's bars (family by family), or those it owns. Owned spans of
// the subdomains of all ranks cover the body once.
std::vector<Span> subdomain_node_spans(const Subdomain& sub, const Lattice& whole, bool owned);
std::vector<Span> subdomain_bar_spans(const Subdomain& sub, const Lattice& whole, bool owned);
// The window's lattice of a subdomain of `whole`.
Lattice window_lattice(const Subdomain& sub, const Lattice& whole);
// The body's number of a bar of the window's lattice `local`.
index_t global_bar(const Subdomain& sub, const Lattice& local, const Lattice& whole, index_t bar);

// The whole body's conditions restricted to the nodes the subdomain owns, in the numbers of
// its window's lattice `local` (the order of each set kept); a condition on none of them is
// left out. Ghost nodes are not included: their owner applies the condition and sends them.
Conditions subdomain_conditions(const Subdomain& sub, const Lattice& whole, const Lattice& local,
                                const Conditions& conditions);

// The last report's energy rows of the subdomains of a run, each subdomain's owned rows in its
// order, subdomain after subdomain. The elastic and dissipated energies per bar row come with
// each row's place in the body's order (its key): summed from zero in key order they are the
// bits of one process. The kinetic energy per node row is summed exactly (ExactSum), in any
// order, as one process sums it.
struct EnergyRows {
  std::vector<double> elastic, damage, fatigue, bar_keys; // per bar row
  std::vector<double> kinetic;                            // per node row
};
// The order in which to visit rows whose keys are `keys` (a permutation that sorts them).
std::vector<std::size_t> key_order(const std::vector<double>& keys);
// The sum from zero of values[order[0]], values[order[1]], ...
double sum_in_order(const std::vector<double>& values, const std::vector<std::size_t>& order);

// The local run of one subdomain: a Simulation over the window, its ghost nodes held, and the
// rows and planes it exchanges with its neighbours.
class SubdomainRun {
public:
  // `local` is the window's lattice (nx, sub.y.local_n(), sub.z.local_n()); `conditions`
  // refer to its nodes, `precracked` to its bars (sorted). The ghost nodes are added as held
  // nodes.
  SubdomainRun(const Subdomain& sub, Lattice local, BarTable table, Conditions conditions,
               SolverOptions options, std::vector<index_t> precracked = {});

  const Subdomain& subdomain() const { return sub_; }
  Simulation& sim() { return sim_; }
  const Simulation& sim() const { return sim_; }

  // Local node number of the global node (i, j, k) of the body (corner or centre), and the
  // inverse; local_node is only valid for nodes inside the window.
  index_t local_node(const NodeAddress& global) const;
  NodeAddress global_address(index_t local) const;
  // Whether this rank owns the local node (integrates it and reports it), or the local bar.
  bool owns(index_t local) const;
  bool owns_bar(index_t local_bar) const;

  // The rows of the last report's energies that this subdomain owns, appended in its order
  // with their keys (EnergyRows): elastic and dissipated energy per bar row, kinetic energy
  // per node row.
  // (After a report step only; the keys alone at any time.)
  void append_owned_energy_rows(EnergyRows& rows) const;
  void append_owned_row_keys(EnergyRows& rows) const;

  // Halo exchange along axis 1 (y) or 2 (z): the doubles to send to the neighbour towards dir
  // (-1 or +1), and the doubles received from it. Both sides agree on the sizes (halo_size,
  // 0 where there is no neighbour).
  std::size_t halo_size(int axis, int dir) const;
  void pack(int axis, int dir, std::vector<double>& out) const;
  void unpack(int axis, int dir, const std::vector<double>& in);
  // The same for any 3 values per window node (node after node) in `values`, instead of the
  // displacements.
  void pack(int axis, int dir, const std::vector<double>& values, std::vector<double>& out) const;
  void unpack(int axis, int dir, const std::vector<double>& in, std::vector<double>& values) const;

private:
  const AxisPart& part(int axis) const { return axis == 1 ? sub_.y : sub_.z; }
  // Local row (axis 1) or plane (axis 2) index sent towards dir, and received from it.
  index_t send_index(int axis, int dir) const;
  index_t recv_index(int axis, int dir) const;
  void check_halo(int axis, int dir, std::size_t size) const; // throws on a wrong size
  // Calls visit(first local node, count) for each run of nodes exchanged at `index` along
  // `axis`, in a fixed order.
  template <class F> void for_each_halo_run(int axis, index_t index, F&& visit) const;
  // Calls bar_row(r, key) and node_row(r) for the owned rows of the local Simulation.
  template <class Bar, class Node> void for_each_owned_row(Bar&& bar_row, Node&& node_row) const;

  Subdomain sub_;
  Simulation sim_;
};

} // namespace ldem
