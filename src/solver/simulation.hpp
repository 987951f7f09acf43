// Explicit central-difference dynamics of the lattice: the time-step loop.
//
// State at step n: displacements u_n (reference coordinates are computed from the
// lattice, so current coordinates are X + u, large displacements included) and u_{n-1},
// which gives the half-step velocities v_{n-1/2} = (u_n - u_{n-1}) / dt. One step:
//   1. bar pass   : every bar's strain, force over current length s = F / l, history,
//                   events (one writer per bar);
//   2. node pass  : each node gathers its bars in a fixed order (RowLink), then
//                   v_{n+1/2} = [(1 - a dt/2) v_{n-1/2} + dt f / m] / (1 + a dt/2),
//                   u_{n+1} = u_n + dt v_{n+1/2}  (a: mass-proportional damping);
//   3. conditions : imposed velocities and their reactions.
// Both passes split work by whole rows, so every number is the same whatever the
// thread count.
#pragma once

#include "energy/ledger.hpp"
#include "lattice/lattice.hpp"
#include "lattice/node_set.hpp"
#include "material/bar_table.hpp"
#include "solver/stable_step.hpp"
#include "solver/time_function.hpp"
#include "util/aligned.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace ldem {

// Degrees of freedom as bits: x = 1, y = 2, z = 4.
using DofMask = std::uint8_t;
inline constexpr DofMask kDofX = 1, kDofY = 2, kDofZ = 4, kDofAll = 7;

struct FixedDofs {
  NodeSet set;
  DofMask dofs = kDofAll;
};

// v = velocity * scale(t) on the chosen DOF of every node of the set.
struct ImposedVelocity {
  NodeSet set;
  DofMask dofs = kDofAll;
  Vec3 velocity;
  TimeFunction scale;
};

// A force `force * scale(t)` [N] on every node of the set.
struct NodalLoad {
  NodeSet set;
  Vec3 force;
  TimeFunction scale;
};

struct Conditions {
  std::vector<FixedDofs> fixed;
  std::vector<ImposedVelocity> velocities;
  std::vector<NodalLoad> loads;
  int plane_strain_axis = -1; // 0, 1, 2: that displacement is zero at every node
};

struct TimeStep {
  enum class Rule { Safety, Given, Paper };
  Rule rule = Rule::Safety;
  double safety = 0.9;  // fraction of the stable step (Rule::Safety)
  double dt = 0.0;      // Rule::Given
  double courant = 0.6; // Rule::Paper: dt = courant L / c, c = sqrt(E_max / rho)
};

struct SolverOptions {
  TimeStep step;
  double damping = 0.0; // mass-proportional damping coefficient a [1/s], C = a M
  // The stable step and dt are given later (set_time_step with a StableStep): a distributed
  // run's window, whose step is the whole body's.
  bool defer_time_step = false;
  // Lines per block of the step's walk (advance_rows); 0: chosen from the line's size. The
  // results do not depend on it; tests vary it to check that.
  int block_lines = 0;
  // Intact bars of a uniform material have their forces computed where their nodes gather
  // them, once at each end, instead of by the bar pass through a buffer, wherever the last
  // step's strains and motions prove that none of them can pass e_p in this step
  // (bar_row_stays_intact; docs/architecture.md). AVX-512 builds only. The results are the
  // same bits either way; tests turn it off to check that.
  bool intact_at_nodes = true;
};

// dt by the rule of `step`: a fraction of the stable step, given, or the paper's Courant
// number at the bar wave speed of the stiffest material, sqrt(E_max / rho). Throws InputError
// for a rule's bad value or a dt that is not positive or above the stable limit.
double time_step_by_rule(const TimeStep& step, const StableStep& stable, double E_max, double rho,
                         double L);

struct Event {
  index_t bar;
  BarState state; // Softening or Broken
  std::uint64_t step;
};

// The order in which events are reported: by step, then bar, then state.
inline bool event_before(const Event& a, const Event& b) {
  if (a.step != b.step)
    return a.step < b.step;
  if (a.bar != b.bar)
    return a.bar < b.bar;
  return a.state < b.state;
}

// A link of a node row (see RowLink) as the step's node kernel reads it. What does not depend
// on where the row lies, only on its kind (corner or centre) and the faces it touches: the
// reference vector from the row's node to the other; the law of the link's intact bars,
// s = k - kl0 / l with kl0 = k l0, and s times `scale` (their area factor over the row's) for
// the first and last bars of their bar row (nodes ilo and ihi - 1); the nodes [ilo, ihi) that
// have the link; which plane buffer holds the bars' forces when the bar pass computes them
// (dk = 0: the row's plane, -1: the one below); whether the row's nodes are the bars' first
// nodes; and the watch length lw = l0 (1 + e_p / 2): the kernel tells whether some bar is
// longer (lw2 = lw^2).
struct LinkConst {
  double rx, ry, rz, k, l0, kl0, scale, lw2;
  std::int64_t ilo, ihi;
  int dk;
  bool first_node;
};

// The lanes of a vector of 8 nodes at a row's end, for one link: those whose nodes have the
// link, and those whose bar is the first or the last of its bar row with a factor of its own.
struct EdgeLanes {
  std::uint8_t has, first, last;
};

// The rest, per row: node i's other node is slot other + i, the force over length of node i's
// bar (from the bar pass) at plane_base + i of a plane buffer, and the bars' row.
struct LinkRef {
  std::int64_t other;
  std::uint32_t bar_row;
  std::int32_t plane_base;
};

class Simulation {
public:
  // `precracked`: bars broken from the start (sorted). Throws InputError for an unstable
  // or invalid time step, damping < 0, or conditions that refer to missing nodes.
  Simulation(Lattice lattice, BarTable table, Conditions conditions, SolverOptions options,
             std::vector<index_t> precracked = {});

  const Lattice& lattice() const { return lat_; }
  const BarTable& table() const { return table_; }
  const StableStep& stable_step() const { return stable_; }
  double dt() const { return dt_; }
  std::uint64_t step_count() const { return step_; }
  double time() const { return static_cast<double>(step_) * dt_; }
  double mass(index_t node) const { return slot_mass_[slot(node)]; }
  // The DOF of a node that are not free: fixed, imposed velocity, or the plane-strain axis.
  DofMask held(index_t node) const { return slot_held_[slot(node)]; }
  // The boundary conditions and loads the simulation was built with.
  const Conditions& conditions() const { return cond_; }

  // Replaces dt before the first step, the half-step velocities kept. Throws InputError after
  // the first step, or for a dt that is not positive or above the stable limit.
  void set_time_step(double dt);
  // The same, with the stable step it is checked against (a run built with
  // SolverOptions::defer_time_step).
  void set_time_step(const StableStep& stable, double dt);
  // The masses and held DOF of every node (what the stable step is computed from).
  std::vector<double> masses() const;
  std::vector<DofMask> held_dofs() const;

  // Initial velocities (before the first step), e.g. a ramp; taken as v_{-1/2}.
  void set_velocity(const std::function<Vec3(Vec3 X)>& v_of_X);

  // One step from t_n to t_{n+1}. With `report`, the energies at t_n are computed during
  // the step and kept in last_report().
  void step(bool report = false);
  const EnergyReport& last_report() const { return report_; }
  // The last report's energies row by row, for distributed runs that sum them across
  // processes in the same order: elastic and dissipated energy per bar row (its family and
  // block indices j, k) and kinetic energy per node row (node_row: its place), in the order of
  // the step. The report's elastic, damage and kinetic energies are their sums in that order
  // (the kinetic energy plus that of imposed-velocity DOF).
  const std::vector<double>& report_bar_elastic() const { return energy_rows_u_; }
  const std::vector<double>& report_bar_damage() const { return energy_rows_d_; }
  const std::vector<double>& report_node_kinetic() const { return row_kinetic_; }
  index_t bar_row_plane(std::size_t r) const { return bar_rows_[r].k; }
  index_t bar_row_line(std::size_t r) const { return bar_rows_[r].j; }
  int bar_row_family(std::size_t r) const { return bar_rows_[r].family; }
  const NodeRow& node_row(std::size_t r) const { return node_rows_[r]; }

  // Events since the last call, in (step, bar) order.
  std::vector<Event> take_events();

  Vec3 displacement(index_t node) const {
    const std::size_t q = slot(node);
    return {ux_[q], uy_[q], uz_[q]};
  }
  Vec3 half_step_velocity(index_t node) const;
  // visit(node, u_n, v_{n-1/2}) for the nodes [first, first + count) in order: what
  // displacement() and half_step_velocity() give, a row at a time.
  template <class F> void for_each_node_state(index_t first, index_t count, F&& visit) const {
    for_each_run(first, count, [&](std::size_t q0, index_t n0, index_t run) {
      for (index_t i = 0; i < run; ++i) {
        const std::size_t q = q0 + i;
        visit(n0 + i, Vec3{ux_[q], uy_[q], uz_[q]},
              Vec3{(ux_[q] - wx_[q]) / dt_, (uy_[q] - wy_[q]) / dt_, (uz_[q] - wz_[q]) / dt_});
      }
    });
  }
  void set_displacement(index_t node, Vec3 u);
  // Halo exchange and state transfers of distributed runs: u_n (or, with `previous`, u_{n-1})
  // of nodes [first, first + count) appended to `out` as an x block, a y block and a z block;
  // and set from such blocks (the halo sets u_n alone: for held ghost nodes u_{n-1} is never
  // read). Likewise the histories of bars [first, first + count).
  void append_displacements(index_t first, index_t count, std::vector<double>& out,
                            bool previous = false) const;
  void assign_displacements(index_t first, index_t count, const double* in, bool previous = false);
  void append_histories(index_t first, index_t count, std::vector<double>& out) const;
  void assign_histories(index_t first, index_t count, const double* in);
  // After the displacements and histories are assigned: the step count, the energy
  // accumulators (Ledger::state), the last report and the events not yet taken: what a
  // checkpoint holds (io/checkpoint.hpp) besides the arrays. The rows' damage flags are derived
  // again from the histories.
  void restore_progress(std::uint64_t step, const Ledger::State& ledger, const EnergyReport& report,
                        std::vector<Event> pending);
  const Ledger::State& ledger_state() const { return ledger_.state(); }
  // The last report's exact parts, which a distributed run adds over its processes before
  // rounding: the external work, twice the damping dissipation, and the kinetic energy of the
  // imposed-velocity DOF (part of the kinetic energy, not of report_node_kinetic's rows).
  const ExactSum& report_work() const { return report_work_; }
  const ExactSum& report_twice_damping() const { return report_damping2_; }
  const ExactSum& report_condition_kinetic() const { return cond_kinetic_; }
  void set_half_step_velocity(index_t node, Vec3 v);
  BarState bar_state(index_t bar) const;
  double bar_history(index_t bar) const { return h_[bar]; }
  // Axial force of a bar at the current displacements and history [N].
  double bar_force(index_t bar) const;

  // Internal forces f_int (the sum of bar forces acting on each node) and the stored
  // energy at the current displacements, history unchanged. For tests and probes.
  void internal_forces(std::vector<double>& fx, std::vector<double>& fy,
                       std::vector<double>& fz) const;
  double stored_energy() const;
  struct BarEnergies {
    double elastic = 0.0, damage = 0.0;
  };
  // Elastic and dissipated energy of all bars, every bar through the bar law, summed row by
  // row (deterministic): the reference the report steps' energies are tested against.
  BarEnergies bar_energies() const;
  // Per bar: state (0 intact, 1 softening, 2 broken), damage (dissipated / Gf A^f), axial force.
  void bar_snapshot(std::vector<std::uint8_t>& state, std::vector<double>& damage,
                    std::vector<double>& force) const;
  // Force of its bars on one node at the current state (from the bar law).
  Vec3 node_force(index_t node) const;
  // The nodal load at the current step's start on a node (zero without loads).
  Vec3 nodal_load(index_t node) const {
    return px_.empty() ? Vec3{} : Vec3{px_[slot(node)], py_[slot(node)], pz_[slot(node)]};
  }

  // The first node whose displacement is not finite or beyond 1e3 times the body's size (a
  // numerical blow-up), or num_nodes() if none.
  index_t first_bad_node() const;
  // The first node with a displacement component beyond `limit` (or not finite), or
  // num_nodes() if none.
  index_t first_node_beyond(double limit) const;

  // Bar rows in all, and those whose bars took the intact fast path in the last step
  // (SolverOptions::intact_at_nodes).
  std::size_t bar_row_count() const { return bar_rows_.size(); }
  std::size_t intact_fast_rows() const {
    return static_cast<std::size_t>(std::count(row_fast_.begin(), row_fast_.end(), 1));
  }
  // The fast path's bound on how far `node` moved in the last step: the largest |u_{n+1} - u_n|
  // over its node row, infinite when not known (0 when the fast path is off).
  double motion_bound(index_t node) const;
  // Whether this build has that fast path at all (AVX-512 builds; elsewhere every bar takes
  // the bar pass, whatever SolverOptions::intact_at_nodes says).
  static bool intact_at_nodes_built();

  std::uint64_t broken_count() const;
  std::uint64_t softening_count() const;
  // Bytes per module held by the simulation's arrays (the state and what the step loop reads).
  double bytes_per_module() const;

private:
  // A node's place in the step loop's node arrays, which hold each row of nodes from a cache
  // line on (slots_: the lattice's rows, each padded to whole lines of 8 doubles; the padding
  // stays zero), so that a row's vectors load and store whole lines.
  std::size_t slot(index_t node) const {
    const index_t nc = lat_.num_corners(), nx = lat_.nx();
    if (node < nc)
      return static_cast<std::size_t>(slots_.corner_row) * (node / (nx + 1)) + node % (nx + 1);
    const index_t m = node - nc;
    return static_cast<std::size_t>(slots_.centre_first + slots_.centre_row * (m / nx)) + m % nx;
  }
  // visit(first slot, first node, count) for the runs of nodes [first, first + count) that lie
  // in one row.
  template <class F> void for_each_run(index_t first, index_t count, F&& visit) const {
    const index_t nc = lat_.num_corners(), end = first + count;
    for (index_t n = first; n < end;) {
      const index_t row = n < nc ? lat_.nx() + 1 : lat_.nx();
      const index_t i = n < nc ? n % row : (n - nc) % row;
      const index_t run = std::min(end - n, row - i);
      visit(slot(n), n, run);
      n += run;
    }
  }
  template <bool Damped, bool Loads, bool Report> void advance_rows();
  // visit(row, first bar, bar count, k = E A / l0, extension(i) = l - l0) for every bar row
  // never strained past e_p, rows in parallel; none when the material varies per bar.
  template <class F> void for_each_intact_row(F&& visit) const;
  // The bar rows of a line into its plane's force buffer `s`; with `energies`, the elastic
  // energy of each row into energy_rows_u_. Rows whose bars take the intact fast path this
  // step (row_fast_) are left to the node pass.
  void bar_rows(std::size_t line, double* s, bool energies);
  // Whether bar row r's bars are all intact and provably stay below e_p in this step.
  bool bar_row_stays_intact(std::size_t r) const;
  // The node row of a node, and the last step's motion of a row made unknown (its bars then
  // take the bar pass until a step has measured it again).
  std::size_t node_row_of(index_t node) const;
  void forget_motion(index_t first, index_t count);
  // The bar forces of line l from a plane buffer into a packed store (Pack), or back.
  template <bool Pack> void move_bar_line(std::size_t l, double* plane, double* packed) const;
  // A report step's elastic and dissipated energy of all bars, per row in energy_rows_u_ and
  // energy_rows_d_: the elastic energies the bar pass has put there, the dissipated energy
  // kept per row (row_dissipated_) and recomputed where a history has changed.
  BarEnergies report_bar_energies();
  // Row r's dissipated energy, and with `elastic` its elastic energy, by the bar law.
  BarEnergies law_row_energies(std::size_t r, bool elastic) const;
  // lane(i, strain, law, history) for each bar i of row r by the bar law, in a loop GCC can
  // vectorise; returns the row's bar count. PerBar: the material varies per bar.
  template <bool PerBar, class F> index_t visit_law_row(std::size_t r, F&& lane) const;
  // visit(r) for every bar row where take(r), rows in parallel (to go through the bar law).
  template <class P, class F> void for_each_row_by_law(P&& take, F&& visit) const;
  // visit(first bar, bar count, k = E A / l0, extension(i) = l - l0) for intact bar row r.
  template <class F> void visit_intact_row(std::size_t r, F&& visit) const;
  // Nodes of plane rows [begin, end), with the bar forces of their plane and the one below.
  template <bool Damped, bool Loads, bool Report>
  void node_rows_range(std::size_t line, const double* s_plane, const double* s_below);
  void mark_damaged_rows();
  void apply_loads(double t);
  void apply_velocities(double t, bool report);
  void compute_energies(bool report);

  Lattice lat_;
  BarTable table_;
  Conditions cond_;
  SolverOptions opt_;
  StableStep stable_;
  double dt_ = 0.0;
  std::uint64_t step_ = 0;

  std::vector<NodeRow> node_rows_;
  std::vector<std::uint8_t> row_held_; // per node row: some DOF is fixed or imposed
  // The links of the node rows as the node kernel reads them: LinkConst once per kind of row
  // (corner or centre, and the faces it touches), LinkRef per row. A kind of row: its length
  // and links; the vectors of 8 nodes from i = lo on and ending by hi have every link on every
  // lane and no end bar to scale; the others, in order, take their lanes from edge_lanes_
  // (kMaxRowLinks per such vector, from edge_begin on).
  struct RowKind {
    std::int64_t n;
    int links;
    std::int64_t lo, hi;
    std::size_t edge_begin;
  };
  std::vector<LinkConst> link_const_; // kMaxRowLinks per kind of row
  std::vector<EdgeLanes> edge_lanes_;
  std::vector<RowKind> row_kinds_;
  std::vector<std::uint16_t> row_kind_; // per node row
  std::vector<std::uint8_t> row_whole_; // per node row: the portable kernel's one pass (see there)
  std::vector<LinkRef> link_ref_;       // kMaxRowLinks per node row
  struct BarRow {
    int family;
    index_t j, k;
    double factor, end_factor;  // area factors of the row's bars (inner, first/last)
    std::size_t a_slot, b_slot; // slots of the first and second nodes of the row's bar i = 0
  };
  std::vector<BarRow> bar_rows_;
  std::vector<std::uint8_t> row_damaged_; // per bar row: some bar has h != e_p
  // The intact fast path (SolverOptions::intact_at_nodes; bar_row_stays_intact). Per bar row:
  // whether its bars take it in this step, the largest (l / l_p)^2 of its bars when last
  // evaluated (infinite when not known), 1 / l_p, the largest (l / l_p)^2 a bar no longer than
  // its watch length can have ((l0 (1 + e_p / 2) / l_p)^2, see LinkConst), whether its first
  // nodes are centres (else corners), and the node rows of its first and second nodes. Per
  // line: whether all its bar rows take the fast path. Per node row: the largest
  // |u_{n+1} - u_n| of its nodes in the last step (infinite when not known).
  bool fast_path_ = false;
  std::vector<std::uint8_t> row_fast_, line_fast_, row_first_centre_;
  std::vector<double> row_ratio_, row_inv_lp_, row_watch_;
  std::vector<std::array<std::uint32_t, 2>> bar_row_nodes_;
  std::vector<double> node_row_motion_;
  // Row ranges of each line (fixed j, k) and the lines of each k-plane.
  struct Line {
    std::size_t bar_begin, bar_end, node_begin, node_end;
  };
  struct Plane {
    std::size_t line_begin, line_end;
  };
  std::vector<Line> lines_;
  std::vector<Plane> planes_;
  int threads_ = 1;
  // fx, fy, fz, fw, three free-DOF rows and the nodes' motion, each of scratch_stride_ (the
  // report's bar energies use the first two too)
  mutable std::vector<AlignedVector<double>> thread_scratch_;
  std::size_t scratch_stride_ = 0;

  // Node arrays of the step loop (structure of arrays, indexed by slot):
  // u_n, and u_{n-1} (overwritten by u_{n+1} during a step, then the two are swapped):
  // v_{n-1/2} = (u_n - u_{n-1}) / dt, so no velocity array is streamed.
  RowNumbering slots_;
  std::size_t slot_count_ = 0;
  AlignedVector<double> ux_, uy_, uz_, wx_, wy_, wz_;
  AlignedVector<double> slot_mass_, slot_inv_mass_;
  AlignedVector<DofMask> slot_held_;   // DOF fixed, imposed or held by plane strain
  AlignedVector<double> px_, py_, pz_; // nodal loads at t_n (only with loads)
  // Slots of the nodes of each imposed velocity and each load.
  std::vector<std::vector<std::size_t>> velocity_slots_, load_slots_;
  // The bar forces gathered at the nodes of the rows with imposed-velocity nodes (x, y and z
  // runs of each such row, from imposed_row_[r], -1 for other rows), and where each imposed
  // node's lie (its x place and its row's length).
  std::vector<std::int64_t> imposed_row_;
  std::vector<double> imposed_force_;
  std::vector<std::vector<std::pair<std::size_t, index_t>>> imposed_force_at_;
  // The node row of each imposed-velocity node; per node row, the largest squared motion of
  // the DOF one condition imposes on its nodes in this step (condition_motion_, scratch), and
  // those summed over the conditions (imposed_motion_; apply_velocities adds it to the row's
  // motion).
  std::vector<std::vector<std::uint32_t>> imposed_node_row_;
  std::vector<double> imposed_motion_, condition_motion_;
  // Bar arrays: the history, the only per-bar state. The bars' force over current length
  // s = F / l lives only in per-thread plane buffers during a step (see advance_rows).
  std::vector<double> h_;
  std::vector<AlignedVector<double>> plane_buffers_; // 3 per thread: two alternating, one top
  // 2 per thread: one bar line per plane, packed (the block's carry, the edge a neighbour reads)
  std::vector<std::vector<double>> line_stores_;
  std::size_t line_store_stride_ = 0; // the most bars a line has
  std::int64_t block_lines_ = 1;      // lines per block of the walk (advance_rows)

  // Per-row partial sums (deterministic reductions) and per-thread scratch.
  std::vector<double> row_damping_, row_load_mid_, row_load_half_, row_kinetic_;
  std::vector<std::vector<Event>> thread_events_;
  std::vector<std::uint64_t> thread_flags_;
  // Imposed-velocity nodes: velocity before the node pass.
  std::vector<std::vector<Vec3>> imposed_v_old_;

  // Sums over the imposed-velocity DOF of the current step (apply_velocities).
  ExactSum cond_work_, cond_work_half_, cond_damping_, cond_kinetic_;
  ExactSum report_work_, report_damping2_; // of the last report (see report_work)

  std::vector<double> energy_rows_u_, energy_rows_d_; // per-row sums of the last report
  // Per bar row: the dissipated energy of its bars when last summed, and whether a history of
  // the row has changed since (set by the bar pass and by mark_damaged_rows).
  std::vector<double> row_dissipated_;
  std::vector<std::uint8_t> row_history_changed_;
  mutable std::vector<std::uint8_t> snapshot_by_law_; // bar_snapshot: intact rows past e_p now
  mutable std::vector<std::size_t> law_rows_;         // the rows taken through the bar law

  Ledger ledger_;
  EnergyReport report_{};
};

} // namespace ldem
