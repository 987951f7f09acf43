// The inside of a Simulation (internal to the solver): its state, the step's layout and
// tables, the boundary conditions as the step applies them, the buffers and the energy sums.
// The public face is solver/simulation.hpp; the step's passes (bar_pass.hpp, node_pass.hpp,
// walk.hpp), the boundary conditions (boundary.cpp) and the evaluations outside the step
// (bar_evaluation.hpp) work on this.
#pragma once

#include "energy/ledger.hpp"
#include "solver/simulation.hpp"
#include "solver/step_layout.hpp"
#include "util/aligned.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace ldem {

// A strain ratio or a motion not yet measured: the intact fast path waits for it.
inline constexpr double kUnknown = std::numeric_limits<double>::infinity();
// SimulationCore::row_fast: a bar row's bars in the bar pass, all of them at the nodes, or those
// outside its damaged span at the nodes and the span in the bar pass.
inline constexpr std::uint8_t kRowByPass = 0, kRowFast = 1, kRowFastAround = 2;

// Whether the node kernel is the AVX-512 one, which takes fast links and can also move the
// nodes (node_row_forces).
#if defined(__AVX512F__)
inline constexpr bool kVectorKernel = true;
#else
inline constexpr bool kVectorKernel = false;
#endif

// A platen as the step applies it (contact.cpp): where it is, and its contacts.
struct PlatenState {
  Vec3 offset, previous; // its displacement at t_n and t_{n-1}
  // The stretch of the sticking spring of each node in touch with friction, by node number
  // (none for a frictionless platen), and the list the step being taken builds.
  struct Stick {
    index_t node;
    double s[3];
  };
  std::vector<Stick> stick, next_stick;
  // This step's touching nodes: slot, force on the node, u_n - u_{n-1} and the spring's energy.
  struct Touch {
    std::size_t slot, row; // its slot and node row
    double f[3], du[3];
    double energy;
  };
  std::vector<Touch> touches;
  std::array<ExactSum, 3> force_sum; // the touches' forces added (this step's, at t_n)
  Vec3 force;                        // and rounded
};

// The boundary conditions and loads as the step applies them (boundary.cpp).
struct Boundary {
  // Slots of the nodes of each imposed velocity and each load.
  std::vector<std::vector<std::size_t>> velocity_slots, load_slots;
  // The bar forces gathered at the nodes of the rows with imposed-velocity nodes (x, y and z
  // runs of each such row, from imposed_row[r], -1 for other rows), and where each imposed
  // node's lie (its x place and its row's length).
  std::vector<std::int64_t> imposed_row;
  std::vector<double> imposed_force;
  std::vector<std::vector<std::pair<std::size_t, index_t>>> imposed_force_at;
  // The node row of each imposed-velocity node, and each condition's rows once each (in the
  // order of their first node); per node row, the largest squared motion of the DOF one
  // condition imposes on its nodes in this step (condition_motion, scratch), and those summed
  // over the conditions (imposed_motion; apply_velocities adds it to the row's motion).
  std::vector<std::vector<std::uint32_t>> imposed_node_row, imposed_rows;
  std::vector<double> imposed_motion, condition_motion;
  // Imposed-velocity nodes: velocity before the node pass.
  std::vector<std::vector<Vec3>> imposed_v_old;
  // Sums over the imposed-velocity DOF of the current step (apply_velocities).
  ExactSum work, work_half, damping, kinetic;
  // The time functions' values the loads were last applied with (apply_loads), empty before.
  std::vector<double> load_scales;
  // The factors of the controlled velocities (Simulation::set_control_factors).
  std::vector<double> control_factors;
  // Factors a script sets on the velocities and loads (Simulation::set_velocity_factor,
  // set_load_factor), one per condition; empty while none has been set (all 1).
  std::vector<double> velocity_factors, load_factors;
  // The platens (Conditions::platens), and the terms of the step's report: the platens' work
  // less the work of their contact forces on the body before t_n, and the springs' energy.
  std::vector<PlatenState> platens;
  ExactSum platen_half, contact_energy;
  // What the platens test each step: runs of stored nodes along x (first slot and node, count,
  // the first node's i plus 1/2 for centre rows, its y and z in the body), and per slot whether
  // the node is one of the body's that this simulation owns (contact.cpp builds them).
  struct ContactRun {
    std::size_t q0;
    index_t n0, count;
    double i0, y, z;
  };
  std::vector<ContactRun> contact_runs;
  std::vector<std::uint8_t> contactable;
  std::vector<std::uint8_t> run_may_touch; // per run, this step's (scratch)
};

struct SimulationCore {
  SimulationCore(Lattice lattice, BarTable table, Conditions conditions, SolverOptions options);

  Lattice lat;
  BarTable table;
  Conditions cond;
  SolverOptions opt;
  StableStep stable;
  double dt = 0.0;
  std::uint64_t step = 0;
  StepLayout layout;

  // Node arrays of the step loop (structure of arrays, indexed by slot): u_n, and u_{n-1}
  // (overwritten by u_{n+1} during a step, then the two are swapped):
  // v_{n-1/2} = (u_n - u_{n-1}) / dt, so no velocity array is streamed.
  UnsetVector<double> ux, uy, uz, wx, wy, wz;
  UnsetVector<double> mass, inv_mass; // (set by the threads together: set-up)
  AlignedVector<DofMask> held;        // DOF fixed, imposed or held by plane strain
  UnsetVector<double> px, py, pz;     // nodal loads at t_n (only with loads)
  std::vector<std::uint8_t> row_held; // per node row: some DOF is fixed or imposed
  // Per node row, with loads or platens: 1 if a load has a node in it, | 2 if a platen touches
  // one of its nodes in this step (empty without either).
  std::vector<std::uint8_t> row_loaded;
  Boundary bc;

  // The law's per-bar state arrays (LawKernels::state_arrays), the only per-bar state. The
  // bars' force over current length s = F / l lives only in per-thread plane buffers during a
  // step (see advance_rows).
  std::vector<UnsetVector<double>> states;
  // Per bar row, the bars [lo, hi) from its first to its last bar that is not pristine (the
  // law's pristine(); {0, 0} in a pristine row): the general kernel takes those, the intact
  // kernels the row's others (bar_rows). A bar never becomes pristine again, so the span only
  // widens, and is the same whether it grew step by step or was found in the states of a resumed
  // run.
  std::vector<std::array<index_t, 2>> damaged_span;
  void widen_damaged(std::size_t r, index_t i) {
    std::array<index_t, 2>& d = damaged_span[r];
    d = d[0] == d[1] ? std::array<index_t, 2>{i, i + 1}
                     : std::array<index_t, 2>{std::min(d[0], i), std::max(d[1], i + 1)};
  }
  // Some bar of row r is not pristine (or is pre-cracked).
  bool row_damaged(std::size_t r) const { return damaged_span[r][0] != damaged_span[r][1]; }
  // The intact fast path (SolverOptions::intact_at_nodes; bar_row_stays_intact). Per bar row:
  // whether its bars take it in this step (kRowFast: all of them; kRowFastAround: those outside
  // its damaged span, whose forces the bar pass computes) and the largest (l / l_p)^2 of its
  // bars outside that span when last evaluated (infinite when not known). Per line: whether all its
  // bar rows take the fast path. Per node row: the largest |u_{n+1} - u_n| of its nodes in the last
  // step (infinite when not known).
  bool fast_path = false;
  // The node kernel without y components (SolverOptions::plane_strain_kernel).
  bool plane_y = false;
  std::vector<std::uint8_t> row_fast, line_fast;
  std::vector<double> row_ratio;
  std::vector<double> node_row_motion;

  int threads = 1;
  // fx, fy, fz, fw, three free-DOF rows and the nodes' motion, each of scratch_stride (the
  // report's bar energies and the cycle count use the first two too, the bar pass the first
  // for the bars whose state changes)
  mutable std::vector<AlignedVector<double>> thread_scratch;
  std::size_t scratch_stride = 0;
  std::vector<AlignedVector<double>> plane_buffers; // 3 per thread: two alternating, one top
  // 2 per thread: one bar line per plane, packed (the block's carry, the edge a neighbour reads)
  std::vector<std::vector<double>> line_stores;
  std::int64_t block_lines = 1; // lines per block of the walk (advance_rows)
  // The walk's slabs of k-planes (advance_rows): thread t takes the planes [slab_start[t],
  // slab_start[t + 1]), placed by balance_slabs for equal times; each plane's time in the walk
  // on each timed step since the last placing (one step in 4: 4 samples of every plane, one
  // after the other), and the steps since then.
  std::vector<std::int64_t> slab_start;
  std::vector<double> plane_busy, plane_cost; // (plane_cost: their medians, typical_costs)
  int busy_steps = 0;
  std::vector<std::vector<Event>> thread_events;

  // Per-row partial sums (deterministic reductions).
  std::vector<double> row_damping, row_load_mid, row_load_half, row_kinetic;
  std::vector<double> energy_rows_u, energy_rows_d; // per-row sums of the last report
  std::vector<double> energy_rows_f;                // fatigue (laws that count cycles)
  // Per bar row: the dissipated energy of its bars when last summed, and whether a state of
  // the row has changed since (set by the bar pass and by mark_damaged_rows).
  std::vector<double> row_dissipated, row_fatigue;
  std::vector<std::uint8_t> row_history_changed;
  mutable std::vector<std::uint8_t> snapshot_by_law; // bar_snapshot: intact rows past e_lim now
  mutable std::vector<std::size_t> law_rows;         // the rows taken through the bar law
  ExactSum report_work, report_damping2;             // of the last report (see report_work)
  Ledger ledger;
  EnergyReport report{};

  std::size_t slot(index_t node) const { return layout.slot(lat, node); }
  // v_{n-1/2} = (u_n - u_{n-1}) / dt of the node in slot q: the state is two displacement
  // fields.
  Vec3 half_step_velocity(std::size_t q) const {
    return {(ux[q] - wx[q]) / dt, (uy[q] - wy[q]) / dt, (uz[q] - wz[q]) / dt};
  }
  template <class F> void for_each_run(index_t first, index_t count, F&& visit) const {
    layout.for_each_run(lat, first, count, visit);
  }
  std::size_t node_row_of(index_t node) const { return layout.node_row_of(lat, node); }
  // The last step's motion of the rows of nodes [first, first + count) made unknown (their
  // bars then take the bar pass until a step has measured it again).
  void forget_motion(index_t first, index_t count);
  // The first bar of bar row r.
  index_t first_bar(std::size_t r) const {
    const BarRow& row = layout.bar_rows[r];
    return lat.bar(static_cast<Family>(row.family), 0, row.j, row.k);
  }
  // The law's state arrays at bar row r's bar i = 0 (index i of the row: its bars [p0, p1) in
  // a compact layout, all of them otherwise; StepLayout::state_origin), at bar `bar`, and at
  // a family's bars in their initial state that a compact layout's absent bars read.
  template <std::size_t N> std::array<double*, N> row_states(std::size_t r) {
    return states_at<N>(*this, static_cast<std::size_t>(layout.state_origin[r]));
  }
  template <std::size_t N> std::array<const double*, N> row_states(std::size_t r) const {
    return states_at<N>(*this, static_cast<std::size_t>(layout.state_origin[r]));
  }
  template <std::size_t N> std::array<double*, N> bar_states(index_t bar) {
    return states_at<N>(*this, layout.state_index(lat, bar));
  }
  template <std::size_t N> std::array<const double*, N> bar_states(index_t bar) const {
    return states_at<N>(*this, layout.state_index(lat, bar));
  }
  template <std::size_t N> std::array<const double*, N> rest_states(int family) const {
    return states_at<N>(*this, layout.rest(family));
  }

private:
  template <std::size_t N, class Self> static auto states_at(Self& self, std::size_t q) {
    std::array<decltype(self.states[0].data()), N> p{};
    for (std::size_t a = 0; a < N; ++a)
      p[a] = self.states[a].data() + q;
    return p;
  }
};

// Conditions as the step applies them: the node sets checked, held DOF marked, the imposed
// rows and their tables (boundary.cpp). Throws InputError for an empty set, a missing node or
// a bad plane-strain axis.
std::vector<DofMask> build_boundary(SimulationCore& core);
// Nodal loads at time t into px, py, pz; with `always`, set again even if their time
// functions have not changed.
void apply_loads(SimulationCore& core, double t, bool always = false);
// The platens' contact forces at u_n added to px, py, pz (after apply_loads, which sets the
// slots the last step's contacts took back to the loads alone), their friction's dissipation
// added to the ledger and, with `report`, the report's terms (contact.cpp).
void apply_platens(SimulationCore& core, double t, bool report);
// After the node pass: the platens move to t_{n+1}; returns the step's platen work less the
// work of the contact forces on the body, which the node pass booked as loads'.
ExactSum finish_platens(SimulationCore& core, double t);
// Imposed velocities at t_{n+1/2} and their reactions' work (into c.bc's sums).
void apply_velocities(SimulationCore& core, double t, bool report);

} // namespace ldem
