// Explicit central-difference dynamics of the lattice: the time-step loop, and the state it
// advances. Inside (solver/core.hpp and the files it lists): the step's layout, its passes and
// the bar law's kernels.
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
#include "material/bar_law.hpp"
#include "material/bar_table.hpp"
#include "solver/stable_step.hpp"
#include "solver/time_function.hpp"
#include "util/aligned.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ldem {

// Degrees of freedom as bits: x = 1, y = 2, z = 4.
using DofMask = std::uint8_t;
inline constexpr DofMask kDofX = 1, kDofY = 2, kDofZ = 4, kDofAll = 7;

struct FixedDofs {
  NodeSet set;
  DofMask dofs = kDofAll;
};

// v = velocity * scale(t) on the chosen DOF of every node of the set; or, for a controlled
// velocity (control >= 0), velocity * the factor set_control_factors() last gave it.
struct ImposedVelocity {
  NodeSet set;
  DofMask dofs = kDofAll;
  Vec3 velocity;
  TimeFunction scale;
  int control = -1;
};

// F = force * weight[i] * scale(t) on node set.nodes[i]; no weights: 1 on every node (a
// traction load weighs each node by its tributary area, the force being the traction).
struct NodalLoad {
  NodeSet set;
  Vec3 force;
  TimeFunction scale;
  std::vector<double> weight{};
  double weight_of(std::size_t i) const { return weight.empty() ? 1.0 : weight[i]; }
};

// A rigid platen: a plane, or a cylinder (a roller support, an indenter), that moves at
// velocity * scale(t) without turning and pushes back the nodes of the body that pass its
// surface, each with a penalty spring k = kappa m (m the node's lumped mass) along the
// surface's normal and, with friction, a tangential spring of the same k whose force is capped
// at friction times the normal force (Coulomb; the spring's stretch is the node's state while
// it touches). docs/model.md, "Platens".
struct Platen {
  std::string name;
  enum class Kind { Plane, Cylinder } kind = Kind::Plane;
  Vec3 point;  // at t = 0: plane, a point of its face; cylinder, a point of its axis
  Vec3 normal; // plane: unit normal of its face, towards the body; cylinder: unit axis
  double radius = 0.0;
  Vec3 velocity;
  TimeFunction scale;
  double friction = 0.0; // Coulomb coefficient
  // The penalty: k = penalty E L on a node of a body face (E the body's largest), that is
  // kappa = 4 penalty E / (rho L^2) per unit mass (rho the smallest); the Simulation sets kappa.
  double penalty = 1.0;
  double kappa = 0.0; // [1/s^2]
};

struct Conditions {
  std::vector<FixedDofs> fixed;
  std::vector<ImposedVelocity> velocities;
  std::vector<NodalLoad> loads;
  std::vector<Platen> platens;
  int plane_strain_axis = -1; // 0, 1, 2: that displacement is zero at every node
  // Per node, 1 where another process owns it (a distributed run's ghost node; empty: all
  // nodes are this simulation's): the platens leave it to its owner. And where the lattice's
  // rows j = 0 and planes k = 0 are in the body (a distributed run's window): the platens are
  // placed in the body's coordinates.
  std::vector<std::uint8_t> not_owned;
  index_t window_j = 0, window_k = 0;
};

// Lumped masses: each module gives rho L^3 / 2 to its centre node and rho L^3 / 16 to each
// of its 8 corners, so a corner carries (modules sharing it) / 16 rho L^3 (1/2 inside,
// 1/4 on a face, 1/8 on an edge, 1/16 at a box corner) and the total is rho V exactly.
// With a density field (`rho_module`, one value per module; empty: rho everywhere) each module
// lumps its own mass the same way. A shaped body's absent modules lump nothing: its nodes that
// no present module has get no mass (the simulation holds them).
UnsetVector<double> lumped_masses(const Lattice& lattice, double rho,
                                  const std::vector<double>& rho_module);

struct LawKernels;
struct SimulationCore;

struct TimeStep {
  enum class Rule { Safety, Given, Paper };
  Rule rule = Rule::Safety;
  double safety = 0.9;  // fraction of the stable step (Rule::Safety)
  double dt = 0.0;      // Rule::Given
  double courant = 0.6; // Rule::Paper: dt = courant L / c, c = sqrt(E_max / rho)
  double end = 0.0;     // the simulated time [s]: at most kMaxSteps steps of dt (0: not checked)
};
// The most steps a run may take: 1e12 (weeks on the smallest body, at a million steps a
// second); a longer one is a typing error in time.end or the step.
inline constexpr double kMaxSteps = 1e12;

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
  // A body in plane strain along y (Conditions::plane_strain_axis = 1): the node kernel leaves
  // out the y components, which are zeros (docs/architecture.md, "Plane strain"). AVX-512
  // builds only. The same bits either way; tests turn it off to check that.
  bool plane_strain_kernel = true;
  // The bar law's kernels (solver/law_kernels.hpp); nullptr: the paper's bilinear law.
  const LawKernels* law = nullptr;
  // Told as the set-up goes through its phases: the phase just done and the seconds since the
  // set-up began (a progress line for a large body); empty: nothing.
  std::function<void(const std::string& phase, double seconds)> setup_progress;
};

// dt by the rule of `step`: a fraction of the stable step, given, or the paper's Courant
// number at the fastest bar wave speed of the body, sqrt(E_max / rho_min). Throws InputError
// for a rule's bad value or a dt that is not positive or above the stable limit, and for a
// mass-proportional damping a with a dt >= 2 (the step's velocity factor
// (1 - a dt / 2) / (1 + a dt / 2) would turn negative: motion reversed each step).
double time_step_by_rule(const TimeStep& step, const StableStep& stable, double E_max,
                         double rho_min, double L, double damping = 0.0);

// The stable step with the platens' penalty springs: omega_max^2 and its bound raised by the
// sum of their kappa (Weyl's inequality), dt and its bound from them.
StableStep with_platens(StableStep stable, const Conditions& conditions);

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

class Simulation {
public:
  // `precracked`: bars broken from the start (sorted). Throws InputError for an unstable
  // or invalid time step, damping < 0, or conditions that refer to missing nodes.
  Simulation(Lattice lattice, BarTable table, Conditions conditions, SolverOptions options,
             std::vector<index_t> precracked = {});
  ~Simulation();
  Simulation(Simulation&&) noexcept;
  Simulation& operator=(Simulation&&) noexcept;

  const Lattice& lattice() const;
  const BarTable& table() const;
  const StableStep& stable_step() const;
  double dt() const;
  std::uint64_t step_count() const;
  double time() const { return static_cast<double>(step_count()) * dt(); }
  double mass(index_t node) const;
  // The DOF of a node that are not free: fixed, imposed velocity, or the plane-strain axis.
  DofMask held(index_t node) const;
  // The boundary conditions and loads the simulation was built with.
  const Conditions& conditions() const;

  // The bar law (SolverOptions::law): its name, and its per-bar state arrays by name.
  std::string_view law_name() const;
  std::span<const StateArray> bar_state_arrays() const;
  // Whether the law has a fatigue life (its energies then include fatigue_dissipated).
  bool counts_cycles() const;

  // Replaces dt before the first step, the half-step velocities kept. Throws InputError after
  // the first step, or for a dt that is not positive or above the stable limit.
  void set_time_step(double dt);
  // The same, with the stable step it is checked against (a run built with
  // SolverOptions::defer_time_step).
  void set_time_step(const StableStep& stable, double dt);
  // The masses and held DOF of every node (what the stable step is computed from).
  std::vector<double> masses() const;
  std::vector<DofMask> held_dofs() const;

  // The factors of the controlled velocities (ImposedVelocity::control indexes them) for the
  // next steps: a controller outside the step sets them before each step (app/run_body.hpp).
  // Before the first call they are 0.
  void set_control_factors(std::span<const double> factors);
  // A factor on imposed velocity i (Conditions::velocities) or nodal load i (Conditions::loads)
  // from the next step on, times what its time function (or control) gives: 0 stops it, -1
  // turns it back (unloading). A script's way to change a loading between steps; 1 until set.
  // Throws InputError for an index beyond the conditions or a factor that is not finite.
  void set_velocity_factor(std::size_t i, double factor);
  void set_load_factor(std::size_t i, double factor);
  double velocity_factor(std::size_t i) const;
  double load_factor(std::size_t i) const;

  // Platen p (Conditions::platens): the force of its contacts on the body at the start of the
  // last step [N], its displacement from where it was at t = 0 [m], and the nodes it touched
  // in the last step.
  Vec3 platen_force(std::size_t p) const;
  Vec3 platen_offset(std::size_t p) const;
  std::size_t platen_contacts(std::size_t p) const;
  // The platens' displacements at t_n and t_{n-1}, 6 doubles per platen, as a checkpoint holds
  // them; and set from such a list (its size checked by the caller).
  std::vector<double> platen_positions() const;
  void set_platen_positions(std::span<const double> positions);
  // The platens' force on the nodes this simulation owns, component by component, exactly
  // (what a distributed run adds over its processes); and the energy their springs hold at the
  // last report.
  const std::array<ExactSum, 3>& platen_force_sum(std::size_t p) const;
  const ExactSum& report_contact() const;
  // The platens' kappa from the body's largest E and smallest density (a distributed run's
  // window takes the body's, not its own), before the time step is set.
  void set_platen_stiffness(double E_max, double rho_min);

  // Initial velocities (before the first step), e.g. a ramp; taken as v_{-1/2}.
  void set_velocity(const std::function<Vec3(Vec3 X)>& v_of_X);

  // One step from t_n to t_{n+1}. With `report`, the energies at t_n are computed during
  // the step and kept in last_report().
  void step(bool report = false);
  const EnergyReport& last_report() const;
  // The last report's energies row by row, for distributed runs that sum them across
  // processes in the same order: elastic and dissipated energy per bar row (its family and
  // block indices j, k) and kinetic energy per node row (node_row: its place), in the order of
  // the step. The report's elastic, damage and kinetic energies are their sums in that order
  // (the kinetic energy plus that of imposed-velocity DOF).
  const std::vector<double>& report_bar_elastic() const;
  const std::vector<double>& report_bar_damage() const;
  const std::vector<double>& report_bar_fatigue() const; // zeros unless the law counts cycles
  const std::vector<double>& report_node_kinetic() const;
  index_t bar_row_plane(std::size_t r) const;
  index_t bar_row_line(std::size_t r) const;
  int bar_row_family(std::size_t r) const;
  const NodeRow& node_row(std::size_t r) const;

  // Events since the last call, in (step, bar) order.
  std::vector<Event> take_events();

  Vec3 displacement(index_t node) const;
  Vec3 half_step_velocity(index_t node) const;
  // u_n and v_{n-1/2} of the nodes [first, first + count), what displacement() and
  // half_step_velocity() give, into u[0, count) and v[0, count).
  void node_states(index_t first, index_t count, Vec3* u, Vec3* v) const;
  void set_displacement(index_t node, Vec3 u);
  // Halo exchange and state transfers of distributed runs: u_n (or, with `previous`, u_{n-1})
  // of nodes [first, first + count) appended to `out` as an x block, a y block and a z block;
  // and set from such blocks (the halo sets u_n alone: for held ghost nodes u_{n-1} is never
  // read). Likewise the values of bars [first, first + count) in the law's state array
  // `array` (bar_state_arrays()).
  void append_displacements(index_t first, index_t count, std::vector<double>& out,
                            bool previous = false) const;
  void assign_displacements(index_t first, index_t count, const double* in, bool previous = false);
  void append_bar_states(std::size_t array, index_t first, index_t count,
                         std::vector<double>& out) const;
  void assign_bar_states(std::size_t array, index_t first, index_t count, const double* in);
  // The whole state as named arrays, what a checkpoint holds besides the run's progress: per
  // node u_n and u_{n-1} along x, y and z, then per bar the law's state arrays by their names.
  // append_state and assign_state take array `array` of that list for nodes or bars
  // [first, first + count).
  struct NamedArray {
    std::string name;
    bool per_bar;
  };
  std::vector<NamedArray> state_arrays() const;
  void append_state(std::size_t array, index_t first, index_t count,
                    std::vector<double>& out) const;
  void assign_state(std::size_t array, index_t first, index_t count, const double* in);
  // After the displacements and states are assigned: the step count, the energy
  // accumulators (Ledger::state), the last report and the events not yet taken: what a
  // checkpoint holds (io/checkpoint.hpp) besides the arrays. The rows' damage flags are derived
  // again from the states.
  void restore_progress(std::uint64_t step, const Ledger::State& ledger, const EnergyReport& report,
                        std::vector<Event> pending);
  const Ledger::State& ledger_state() const;
  // The last report's exact parts, which a distributed run adds over its processes before
  // rounding: the external work, twice the damping dissipation, and the kinetic energy of the
  // imposed-velocity DOF (part of the kinetic energy, not of report_node_kinetic's rows).
  const ExactSum& report_work() const;
  const ExactSum& report_twice_damping() const;
  const ExactSum& report_condition_kinetic() const;
  void set_half_step_velocity(index_t node, Vec3 v);
  BarState bar_state(index_t bar) const;
  // The value of bar `bar` in the law's state array `array`.
  double bar_state_value(std::size_t array, index_t bar) const;
  // The law's state array `array` (bar_state_arrays()), one value per bar, to change in place
  // between steps (cycle jumping moves the lives on).
  std::span<double> bar_state_array(std::size_t array);
  // Axial force of a bar at the current displacements and state [N].
  double bar_force(index_t bar) const;

  // Internal forces f_int (the sum of bar forces acting on each node) and the stored
  // energy at the current displacements, states unchanged. For tests and probes.
  void internal_forces(std::vector<double>& fx, std::vector<double>& fy,
                       std::vector<double>& fz) const;
  double stored_energy() const;
  struct BarEnergies {
    double elastic = 0.0, damage = 0.0;
    double fatigue = 0.0; // released by bars whose fatigue life ran out
  };
  // Elastic and dissipated energy of all bars, every bar through the bar law, summed row by
  // row (deterministic): the reference the report steps' energies are tested against.
  BarEnergies bar_energies() const;
  // Per bar: state (0 intact, 1 softening, 2 broken), damage (dissipated / Gf A^f), axial force
  // and, if asked for, axial strain (l - l0) / l0 (0 for an absent bar).
  void bar_snapshot(std::vector<std::uint8_t>& state, std::vector<double>& damage,
                    std::vector<double>& force, std::vector<double>* strain = nullptr) const;
  // Force of its bars on one node at the current state (from the bar law).
  Vec3 node_force(index_t node) const;
  // The nodal load at the current step's start on a node (zero without loads).
  Vec3 nodal_load(index_t node) const;

  // The first node whose displacement is not finite or beyond 1e3 times the body's size (a
  // numerical blow-up), or num_nodes() if none.
  index_t first_bad_node() const;
  // The threads the step takes from now on: n, within [1, the OpenMP threads when it was
  // built] (its per-thread buffers). The results do not depend on it. Returns the count set.
  int set_threads(int n);
  int threads() const;
  // The first node with a displacement component beyond `limit` (or not finite), or
  // num_nodes() if none.
  index_t first_node_beyond(double limit) const;

  // Bar rows in all, those whose bars took the intact fast path in the last step
  // (SolverOptions::intact_at_nodes), and the damaged rows whose bars outside their damaged
  // span took it.
  std::size_t bar_row_count() const;
  std::size_t intact_fast_rows() const;
  std::size_t fast_rows_around_damage() const;
  // The fast path's bound on how far `node` moved in the last step: the largest |u_{n+1} - u_n|
  // over its node row, infinite when not known (0 when the fast path is off).
  double motion_bound(index_t node) const;
  // Whether this build has that fast path at all (AVX-512 builds; elsewhere every bar takes
  // the bar pass, whatever SolverOptions::intact_at_nodes says).
  static bool intact_at_nodes_built();
  // Whether the node kernel leaves out the y components (SolverOptions::plane_strain_kernel: a
  // body in plane strain along y whose nodes have been given no y displacement or velocity).
  bool plane_strain_kernel_on() const;

  std::uint64_t broken_count() const;
  std::uint64_t softening_count() const;
  // Bytes per module held by the simulation's arrays (the state and what the step loop reads).
  double bytes_per_module() const;

private:
  // The state, the step's layout, tables and buffers (solver/core.hpp), and the kernels of the
  // bar law (solver/law_kernels.hpp).
  std::unique_ptr<SimulationCore> core_;
  const LawKernels* law_ = nullptr;
};

} // namespace ldem
