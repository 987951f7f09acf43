#include "solver/simulation.hpp"

#include "solver/core.hpp"
#include "solver/law_kernels.hpp"
#include "solver/laws.hpp"
#include "util/error.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <omp.h>
#include <stdexcept>

namespace ldem {

UnsetVector<double> lumped_masses(const Lattice& lat, double rho,
                                  const std::vector<double>& rho_m) {
  const double V = lat.L() * lat.L() * lat.L();
  UnsetVector<double> m(lat.num_nodes()); // (every node set below, by the threads together)
  const std::int64_t nodes = lat.num_nodes();
  if (rho_m.empty()) {
    const std::int64_t planes = std::int64_t{lat.nz()} + 1;
#pragma omp parallel for schedule(static) if (nodes > kParallelMinItems)
    for (std::int64_t kk = 0; kk < planes; ++kk) {
      const auto k = static_cast<index_t>(kk);
      for (index_t j = 0; j <= lat.ny(); ++j)
        for (index_t i = 0; i <= lat.nx(); ++i)
          m[lat.corner(i, j, k)] = rho * V * lat.modules_at_corner(i, j, k) / 16.0;
    }
#pragma omp parallel for schedule(static) if (nodes > kParallelMinItems)
    for (std::int64_t c = lat.num_corners(); c < nodes; ++c)
      m[static_cast<std::size_t>(c)] =
          lat.node_present(static_cast<index_t>(c)) ? 0.5 * rho * V : 0.0;
    return m;
  }
#pragma omp parallel for schedule(static) if (nodes > kParallelMinItems)
  for (std::int64_t c = 0; c < nodes; ++c)
    m[static_cast<std::size_t>(c)] = 0.0;
  for (index_t k = 0; k < lat.nz(); ++k)
    for (index_t j = 0; j < lat.ny(); ++j)
      for (index_t i = 0; i < lat.nx(); ++i) {
        const index_t module = lat.centre(i, j, k) - lat.num_corners();
        if (!lat.module_present(i, j, k))
          continue;
        const double mm = rho_m[module] * V;
        m[lat.centre(i, j, k)] = 0.5 * mm;
        for (index_t c = 0; c < 8; ++c)
          m[lat.corner(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))] += mm / 16.0;
      }
  return m;
}

double time_step_by_rule(const TimeStep& step, const StableStep& stable, double E_max,
                         double rho_min, double L, double damping) {
  // The fastest bar wave speed of the body: with a graded or random E or density the paper's
  // rule is taken at the largest E and the smallest density, where the stable step is smallest.
  const double c = std::sqrt(E_max / rho_min);
  double dt = 0.0;
  switch (step.rule) {
  case TimeStep::Rule::Safety:
    if (!(step.safety > 0.0 && step.safety <= 1.0))
      throw InputError(fmt::format(
          "time.safety: expected a fraction of the stable step in (0, 1], got {:g}", step.safety));
    dt = step.safety * stable.dt;
    break;
  case TimeStep::Rule::Given:
    dt = step.dt;
    break;
  case TimeStep::Rule::Paper:
    if (!(step.courant > 0.0 && step.courant <= 1.0))
      throw InputError(
          fmt::format("time.courant: expected a value in (0, 1], got {:g}", step.courant));
    dt = step.courant * L / c;
    break;
  }
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw InputError(fmt::format("time step: expected a positive dt in s, got {:g}", dt));
  if (dt > stable.dt)
    throw InputError(fmt::format(
        "{}: dt = {:.4g} s ({:.3f} L/c{}) is above the stable limit {:.4g} s ({:.3f} L/c) "
        "of this lattice (2 / largest eigenfrequency of M^-1 K); use dt <= {:.4g} s or a safety "
        "fraction",
        step.rule == TimeStep::Rule::Paper ? "time.courant" : "time.dt", dt, dt * c / L,
        step.rule == TimeStep::Rule::Paper ? ", the paper's rule" : "", stable.dt,
        stable.dt * c / L, stable.dt));
  if (step.end > 0.0 && step.end / dt > kMaxSteps)
    throw InputError(fmt::format("time.end: expected at most {:.0e} steps of dt = {:.4g} s, "
                                 "that is end <= {:.4g} s; got {:.4g} s ({:.3g} steps)",
                                 kMaxSteps, dt, kMaxSteps * dt, step.end, step.end / dt));
  if (damping * dt >= 2.0)
    throw InputError(fmt::format(
        "time.damping: expected a coefficient below 2 / dt = {:.4g} 1/s (the step cannot follow "
        "a stronger damping: each step would reverse the motion), got {:.4g} 1/s",
        2.0 / dt, damping));
  return dt;
}

SimulationCore::SimulationCore(Lattice lattice, BarTable bar_table, Conditions conditions,
                               SolverOptions options)
    : lat(std::move(lattice)), table(std::move(bar_table)), cond(std::move(conditions)),
      opt(options) {}

void SimulationCore::forget_motion(index_t first, index_t count) {
  for_each_run(first, count, [&](std::size_t, index_t n0, index_t) {
    node_row_motion[node_row_of(n0)] = kUnknown;
  });
}

StableStep with_platens(StableStep stable, const Conditions& conditions) {
  // A platen's springs add kappa m to a touching node's stiffness along each direction
  // (normal and sticking springs alike), so M^-1/2 K_c M^-1/2 is at most kappa on every DOF,
  // and by Weyl's inequality omega_max^2 grows by at most the sum of the platens' kappa (a node
  // may touch several).
  double kappa = 0.0;
  for (const Platen& p : conditions.platens)
    kappa += p.kappa;
  if (kappa > 0.0) {
    stable.omega_max = std::sqrt(stable.omega_max * stable.omega_max + kappa);
    stable.omega_bound = std::sqrt(stable.omega_bound * stable.omega_bound + kappa);
    stable.dt = 2.0 / stable.omega_max;
    stable.dt_bound = 2.0 / stable.omega_bound;
  }
  return stable;
}

Simulation::Simulation(Lattice lattice, BarTable table, Conditions conditions,
                       SolverOptions options, std::vector<index_t> precracked)
    : core_(std::make_unique<SimulationCore>(std::move(lattice), std::move(table),
                                             std::move(conditions), options)),
      law_(options.law ? options.law : &default_law()) {
  SimulationCore& c = *core_;
  if (!(c.opt.damping >= 0.0) || !std::isfinite(c.opt.damping))
    throw InputError(
        fmt::format("damping: expected a coefficient >= 0 in 1/s, got {:g}", c.opt.damping));
  const auto setup_start = std::chrono::steady_clock::now();
  const auto done = [&](const std::string& phase) {
    if (c.opt.setup_progress)
      c.opt.setup_progress(phase, std::chrono::duration<double>(std::chrono::steady_clock::now() -
                                                               setup_start)
                                      .count());
  };
  c.layout = build_step_layout(c.lat, c.table, [&](int f, index_t first_bar, index_t n) {
    return law_->row_elastic_limit(c.table, f, first_bar, n);
  });
  done("step layout");
  const std::size_t slots = c.layout.slot_count;
  // Masses and held DOF by node number while the step is set up, then in the slots only.
  UnsetVector<double> mass = lumped_masses(c.lat, c.table.spec().rho, c.table.rho_module());
  c.mass.resize(slots);
  c.inv_mass.resize(slots);
#pragma omp parallel for schedule(static) if (slots > kParallelMinItems)
  for (std::int64_t q = 0; q < static_cast<std::int64_t>(slots); ++q) {
    c.mass[static_cast<std::size_t>(q)] = 0.0;
    c.inv_mass[static_cast<std::size_t>(q)] = 0.0;
  }
  // The nodes of a shaped body's box that no present module has: no mass and no bar with a
  // stiffness, held where they are (a unit mass keeps the arithmetic finite; its node never
  // moves, so it adds no energy).
  const auto nodes = static_cast<std::int64_t>(c.lat.num_nodes());
#pragma omp parallel for schedule(static) if (nodes > kParallelMinItems)
  for (std::int64_t m = 0; m < nodes; ++m) {
    const auto n = static_cast<index_t>(m);
    if (!(mass[n] > 0.0))
      mass[n] = 1.0;
    if (const std::size_t q = c.slot(n); c.layout.stored(q)) {
      c.mass[q] = mass[n];
      c.inv_mass[q] = 1.0 / mass[n];
    }
  }
  // (The block the absent nodes outside their rows' windows read, StepLayout::zero_slot.)
  if (c.layout.compact()) {
    std::fill(c.mass.begin() + static_cast<std::ptrdiff_t>(c.layout.zero_slot), c.mass.end(), 1.0);
    std::fill(c.inv_mass.begin() + static_cast<std::ptrdiff_t>(c.layout.zero_slot),
              c.inv_mass.end(), 1.0);
  }
  done("masses");
  // The six arrays, zeroed by the threads together (their first writes touch their pages); the
  // stable step's estimate borrows them first if they have a slot for every node (below).
  UnsetVector<double>* const arrays[] = {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz};
  const auto zero_arrays = [&] {
    const auto count = static_cast<std::int64_t>(slots);
#pragma omp parallel for schedule(static) if (count > kParallelMinItems)
    for (std::int64_t q = 0; q < count; ++q)
      for (UnsetVector<double>* a : arrays)
        (*a)[static_cast<std::size_t>(q)] = 0.0;
  };
  for (UnsetVector<double>* a : arrays)
    a->resize(slots);
  const bool lend = !c.opt.defer_time_step && slots >= c.lat.num_nodes();
  if (!lend)
    zero_arrays();
  done("displacements");
  set_platen_stiffness(c.table.ranges().E[1], c.table.ranges().rho[0]);
  const std::vector<DofMask> held = build_boundary(c);
  done("supports and loads");
  // The bar states' arrays, one per state array of the law (set by init_states below).
  c.states.resize(law_->state_arrays.size());
  for (UnsetVector<double>& a : c.states)
    a.resize(c.layout.state_count);
  if (!c.opt.defer_time_step) {
    // The displacement arrays lend their memory to the estimate's vectors and the bar states'
    // to its other arrays where they have room, so that it needs no more memory than the steps
    // do; the displacements zeroed after.
    StableStepScratch scratch;
    for (int a = 0; a < 6 && lend; ++a)
      scratch.v[a] = arrays[a]->data();
    std::size_t lent = 6;
    for (UnsetVector<double>& a : c.states) {
      for (std::size_t at = 0; lend && lent < 10 && at + c.lat.num_nodes() <= a.size();
           at += c.lat.num_nodes())
        scratch.v[lent++] = a.data() + at;
    }
    c.stable = with_platens(
        compute_stable_step(c.lat, c.table, mass, held, nullptr, lend ? &scratch : nullptr),
        c.cond);
    if (lend)
      zero_arrays();
    c.dt = time_step_by_rule(c.opt.step, c.stable, c.table.ranges().E[1], c.table.ranges().rho[0],
                             c.lat.L(), c.opt.damping);
    done(fmt::format("stable step ({} Lanczos iterations)", c.stable.iterations));
  }
  law_->init_states(c, precracked);
  law_->mark_damaged_rows(c);
  done("bar states");
  // The intact fast path: nothing is known of the strains or the motion before the first step.
  // (Without AVX-512 it would take a square root and a division for every bar at each end:
  // slower than the bar pass, so it is off.) Only rows whose bars share their stiffness take
  // it (BarRow::stiffness): off where there are none.
  c.fast_path = c.opt.intact_at_nodes && kVectorKernel &&
                std::any_of(c.layout.bar_rows.begin(), c.layout.bar_rows.end(),
                            [](const BarRow& r) { return !r.own_stiffness(); });
  // A body in plane strain along y: the node kernel leaves out the y components (every node's
  // y is held at 0), unless some node is given a y displacement or velocity.
  c.plane_y = c.opt.plane_strain_kernel && kVectorKernel && c.cond.plane_strain_axis == 1;
  c.row_fast.assign(c.layout.bar_rows.size(), 0);
  c.line_fast.assign(c.layout.lines.size(), 0);
  c.node_row_motion.assign(c.layout.node_rows.size(), kUnknown);
  c.threads = omp_get_max_threads();
  c.plane_buffers.resize(3 * static_cast<std::size_t>(c.threads));
  for (auto& b : c.plane_buffers)
    b.assign(c.lat.plane_buffer_size(), 0.0);
  c.line_stores.resize(2 * static_cast<std::size_t>(c.threads));
  for (auto& b : c.line_stores)
    b.assign(c.layout.planes.size() * c.layout.line_store_stride, 0.0);
  // About 128 KiB of bar forces per block: with the plane below's and the displacements they
  // read, well inside a core's L2 cache (measured on 64^3: 16 lines, 5 to 10 % faster than
  // whole planes on 2 threads; 8 lines slower than 16).
  const auto line_bytes =
      static_cast<std::int64_t>(8 * std::max<std::size_t>(c.layout.line_store_stride, 1));
  c.block_lines = c.opt.block_lines > 0 ? c.opt.block_lines
                                        : std::clamp<std::int64_t>((128 << 10) / line_bytes, 8, 64);
  // fx, fy, fz, a fourth row for the ledger sums and three for the free-DOF factors, each
  // starting on a cache line.
  c.scratch_stride = round_up_to_line(c.lat.nx() + 1ull);
  c.thread_scratch.resize(static_cast<std::size_t>(c.threads));
  for (auto& sc : c.thread_scratch)
    sc.resize(8 * c.scratch_stride);
  c.energy_rows_u.assign(c.layout.bar_rows.size(), 0.0);
  c.energy_rows_d.assign(c.layout.bar_rows.size(), 0.0);
  c.energy_rows_f.assign(c.layout.bar_rows.size(), 0.0);
  c.law_rows.reserve(c.layout.bar_rows.size());
  const std::size_t nrows = c.layout.node_rows.size();
  c.row_damping.assign(nrows, 0.0);
  c.row_load_mid.assign(nrows, 0.0);
  c.row_load_half.assign(nrows, 0.0);
  c.row_kinetic.assign(nrows, 0.0);
  c.thread_events.resize(static_cast<std::size_t>(c.threads));
  for (auto& ev : c.thread_events)
    ev.reserve(1024);
  done("buffers");
}

Simulation::~Simulation() = default;
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;

const Lattice& Simulation::lattice() const {
  return core_->lat;
}
const BarTable& Simulation::table() const {
  return core_->table;
}
const StableStep& Simulation::stable_step() const {
  return core_->stable;
}
double Simulation::dt() const {
  return core_->dt;
}
std::uint64_t Simulation::step_count() const {
  return core_->step;
}
double Simulation::mass(index_t node) const {
  return core_->mass[core_->slot(node)];
}
DofMask Simulation::held(index_t node) const {
  return core_->held[core_->slot(node)];
}
const Conditions& Simulation::conditions() const {
  return core_->cond;
}
std::string_view Simulation::law_name() const {
  return law_->name;
}
bool Simulation::counts_cycles() const {
  return law_->count_cycles != nullptr;
}
std::span<const StateArray> Simulation::bar_state_arrays() const {
  return law_->state_arrays;
}
const EnergyReport& Simulation::last_report() const {
  return core_->report;
}
const std::vector<double>& Simulation::report_bar_elastic() const {
  return core_->energy_rows_u;
}
const std::vector<double>& Simulation::report_bar_damage() const {
  return core_->energy_rows_d;
}
const std::vector<double>& Simulation::report_bar_fatigue() const {
  return core_->energy_rows_f;
}
const std::vector<double>& Simulation::report_node_kinetic() const {
  return core_->row_kinetic;
}
index_t Simulation::bar_row_plane(std::size_t r) const {
  return core_->layout.bar_rows[r].k;
}
index_t Simulation::bar_row_line(std::size_t r) const {
  return core_->layout.bar_rows[r].j;
}
int Simulation::bar_row_family(std::size_t r) const {
  return core_->layout.bar_rows[r].family;
}
const NodeRow& Simulation::node_row(std::size_t r) const {
  return core_->layout.node_rows[r];
}
const Ledger::State& Simulation::ledger_state() const {
  return core_->ledger.state();
}
const ExactSum& Simulation::report_work() const {
  return core_->report_work;
}
const ExactSum& Simulation::report_twice_damping() const {
  return core_->report_damping2;
}
const ExactSum& Simulation::report_condition_kinetic() const {
  return core_->bc.kinetic;
}
Vec3 Simulation::nodal_load(index_t node) const {
  const SimulationCore& c = *core_;
  return c.px.empty() ? Vec3{} : Vec3{c.px[c.slot(node)], c.py[c.slot(node)], c.pz[c.slot(node)]};
}
std::size_t Simulation::bar_row_count() const {
  return core_->layout.bar_rows.size();
}
std::size_t Simulation::intact_fast_rows() const {
  return static_cast<std::size_t>(
      std::count(core_->row_fast.begin(), core_->row_fast.end(), kRowFast));
}
std::size_t Simulation::fast_rows_around_damage() const {
  return static_cast<std::size_t>(
      std::count(core_->row_fast.begin(), core_->row_fast.end(), kRowFastAround));
}
bool Simulation::plane_strain_kernel_on() const {
  return core_->plane_y;
}
bool Simulation::intact_at_nodes_built() {
  return kVectorKernel;
}
double Simulation::motion_bound(index_t node) const {
  return core_->node_row_motion[core_->node_row_of(node)];
}

void Simulation::set_control_factors(std::span<const double> factors) {
  core_->bc.control_factors.assign(factors.begin(), factors.end());
}

namespace {
void set_factor(std::vector<double>& factors, std::size_t count, std::size_t i, double factor,
                const char* what) {
  if (i >= count)
    throw InputError(fmt::format("{} {}: expected an index below {}, got {}", what, i, count, i));
  if (!std::isfinite(factor))
    throw InputError(fmt::format("{} {}: expected a finite factor, got {}", what, i, factor));
  factors.resize(count, 1.0);
  factors[i] = factor;
}
} // namespace

void Simulation::set_velocity_factor(std::size_t i, double factor) {
  set_factor(core_->bc.velocity_factors, core_->cond.velocities.size(), i, factor, "velocity");
}
void Simulation::set_load_factor(std::size_t i, double factor) {
  set_factor(core_->bc.load_factors, core_->cond.loads.size(), i, factor, "load");
}
double Simulation::velocity_factor(std::size_t i) const {
  return i < core_->bc.velocity_factors.size() ? core_->bc.velocity_factors[i] : 1.0;
}
double Simulation::load_factor(std::size_t i) const {
  return i < core_->bc.load_factors.size() ? core_->bc.load_factors[i] : 1.0;
}

void Simulation::set_velocity(const std::function<Vec3(Vec3)>& v_of_X) {
  for (index_t n = 0; n < core_->lat.num_nodes(); ++n) {
    const Vec3 v = v_of_X(core_->lat.position(n));
    const DofMask h = held(n);
    set_half_step_velocity(
        n, {(h & kDofX) ? 0.0 : v.x, (h & kDofY) ? 0.0 : v.y, (h & kDofZ) ? 0.0 : v.z});
  }
}

void Simulation::set_time_step(const StableStep& stable, double dt) {
  if (core_->step != 0)
    throw InputError("time step: dt can only change before the first step");
  core_->stable = stable;
  set_time_step(dt);
}

void Simulation::set_time_step(double dt) {
  SimulationCore& c = *core_;
  if (c.step != 0)
    throw InputError("time step: dt can only change before the first step");
  if (!(dt > 0.0) || dt > c.stable.dt)
    throw InputError(fmt::format("time step: expected 0 < dt <= {:.4g} s (the stable limit), "
                                 "got {:g}",
                                 c.stable.dt, dt));
  for (std::size_t q = 0; q < c.layout.slot_count; ++q) {
    // (Before a deferred dt is first set, the nodes are at rest.)
    const double vx = c.dt > 0.0 ? (c.ux[q] - c.wx[q]) / c.dt : 0.0;
    const double vy = c.dt > 0.0 ? (c.uy[q] - c.wy[q]) / c.dt : 0.0;
    const double vz = c.dt > 0.0 ? (c.uz[q] - c.wz[q]) / c.dt : 0.0;
    c.wx[q] = c.ux[q] - dt * vx;
    c.wy[q] = c.uy[q] - dt * vy;
    c.wz[q] = c.uz[q] - dt * vz;
  }
  c.dt = dt;
}

Vec3 Simulation::displacement(index_t node) const {
  const SimulationCore& c = *core_;
  const std::size_t q = c.slot(node);
  return {c.ux[q], c.uy[q], c.uz[q]};
}

Vec3 Simulation::half_step_velocity(index_t node) const {
  return core_->half_step_velocity(core_->slot(node));
}

void Simulation::node_states(index_t first, index_t count, Vec3* u, Vec3* v) const {
  const SimulationCore& c = *core_;
  c.for_each_run(first, count, [&](std::size_t q0, index_t n0, index_t run) {
    for (index_t i = 0; i < run; ++i) {
      const std::size_t q = q0 + i, o = n0 + i - first;
      u[o] = {c.ux[q], c.uy[q], c.uz[q]};
      v[o] = c.half_step_velocity(q);
    }
  });
}

void Simulation::set_half_step_velocity(index_t node, Vec3 v) {
  SimulationCore& c = *core_;
  const std::size_t q = c.slot(node);
  if (!c.layout.stored(q))
    return; // an absent node stays at rest
  c.wx[q] = c.ux[q] - c.dt * v.x;
  c.wy[q] = c.uy[q] - c.dt * v.y;
  c.wz[q] = c.uz[q] - c.dt * v.z;
  if (c.uy[q] != 0.0 || c.wy[q] != 0.0)
    c.plane_y = false; // (the y of a body in plane strain is not where the kernel assumes it)
}

void Simulation::set_displacement(index_t node, Vec3 u) {
  SimulationCore& c = *core_;
  c.forget_motion(node, 1);
  const Vec3 v = half_step_velocity(node);
  const std::size_t q = c.slot(node);
  if (!c.layout.stored(q))
    return; // an absent node stays at rest
  c.ux[q] = u.x;
  c.uy[q] = u.y;
  c.uz[q] = u.z;
  set_half_step_velocity(node, v);
}

void Simulation::append_displacements(index_t first, index_t count, std::vector<double>& out,
                                      bool previous) const {
  const SimulationCore& c = *core_;
  for (const UnsetVector<double>* u : {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz})
    if ((u == &c.wx || u == &c.wy || u == &c.wz) == previous)
      c.for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
        out.insert(out.end(), u->begin() + q, u->begin() + q + run);
      });
}

void Simulation::assign_displacements(index_t first, index_t count, const double* in,
                                      bool previous) {
  SimulationCore& c = *core_;
  if (!previous)
    c.forget_motion(first, count);
  for (UnsetVector<double>* u : {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz})
    if ((u == &c.wx || u == &c.wy || u == &c.wz) == previous)
      c.for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
        if (c.layout.stored(q)) // (an absent node stays at rest)
          std::copy(in, in + run, u->begin() + static_cast<std::ptrdiff_t>(q));
        if ((u == &c.uy || u == &c.wy) &&
            std::any_of(in, in + run, [](double y) { return y != 0.0; }))
          c.plane_y = false; // (as in set_half_step_velocity)
        in += run;
      });
}

void Simulation::append_bar_states(std::size_t array, index_t first, index_t count,
                                   std::vector<double>& out) const {
  const SimulationCore& c = *core_;
  const auto& a = c.states[array];
  c.layout.for_each_state_run(c.lat, first, count, [&](std::size_t q, index_t, index_t run) {
    const auto at = a.begin() + static_cast<std::ptrdiff_t>(q);
    out.insert(out.end(), at, at + run);
  });
}

void Simulation::assign_bar_states(std::size_t array, index_t first, index_t count,
                                   const double* in) {
  SimulationCore& c = *core_;
  c.layout.for_each_state_run(c.lat, first, count, [&](std::size_t q, index_t, index_t run) {
    if (c.layout.state_stored(q)) // (an absent bar keeps its initial state)
      std::copy(in, in + run, c.states[array].begin() + static_cast<std::ptrdiff_t>(q));
    in += run;
  });
}

namespace {
// u_n, then u_{n-1}, each along x, y and z: the node arrays of the state.
constexpr const char* kNodeArrays[6] = {"u.x",          "u.y",          "u.z",
                                        "u_previous.x", "u_previous.y", "u_previous.z"};
} // namespace

std::vector<Simulation::NamedArray> Simulation::state_arrays() const {
  std::vector<NamedArray> out;
  for (const char* name : kNodeArrays)
    out.push_back({name, false});
  for (const StateArray& a : law_->state_arrays)
    out.push_back({std::string(a.name), true});
  // The sticking springs' stretch of each frictional platen, per node (0 where none).
  for (const Platen& p : core_->cond.platens)
    if (p.friction > 0.0)
      for (const char* e : {"x", "y", "z"})
        out.push_back({"platen." + p.name + ".stretch." + e, false});
  return out;
}

namespace {
// The frictional platen and the component of state array `array` past the law's arrays.
std::pair<std::size_t, int> stretch_array(const Conditions& cond, std::size_t array) {
  for (std::size_t p = 0; p < cond.platens.size(); ++p)
    if (cond.platens[p].friction > 0.0) {
      if (array < 3)
        return {p, static_cast<int>(array)};
      array -= 3;
    }
  throw std::logic_error("state array out of range");
}
} // namespace

void Simulation::append_state(std::size_t array, index_t first, index_t count,
                              std::vector<double>& out) const {
  const std::size_t laws = std::size(kNodeArrays) + law_->state_arrays.size();
  if (array >= laws) {
    const auto [p, e] = stretch_array(core_->cond, array - laws);
    const std::size_t at = out.size();
    out.resize(at + count, 0.0);
    if (p < core_->bc.platens.size())
      for (const PlatenState::Stick& st : core_->bc.platens[p].stick)
        if (st.node >= first && st.node < first + count)
          out[at + (st.node - first)] = st.s[e];
    return;
  }
  if (array >= std::size(kNodeArrays)) {
    append_bar_states(array - std::size(kNodeArrays), first, count, out);
    return;
  }
  const SimulationCore& c = *core_;
  const UnsetVector<double>* u[6] = {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz};
  c.for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
    out.insert(out.end(), u[array]->begin() + q, u[array]->begin() + q + run);
  });
}

void Simulation::assign_state(std::size_t array, index_t first, index_t count, const double* in) {
  const std::size_t laws = std::size(kNodeArrays) + law_->state_arrays.size();
  if (array >= laws) {
    const auto [p, e] = stretch_array(core_->cond, array - laws);
    std::vector<PlatenState>& platens = core_->bc.platens;
    platens.resize(core_->cond.platens.size());
    std::vector<PlatenState::Stick>& stick = platens[p].stick;
    for (index_t i = 0; i < count; ++i) {
      const index_t node = first + i;
      auto it = std::lower_bound(stick.begin(), stick.end(), node,
                                 [](const PlatenState::Stick& a, index_t n) { return a.node < n; });
      if (it != stick.end() && it->node == node)
        it->s[e] = in[i];
      else if (in[i] != 0.0)
        stick.insert(it, {node, {e == 0 ? in[i] : 0.0, e == 1 ? in[i] : 0.0,
                                 e == 2 ? in[i] : 0.0}});
    }
    return;
  }
  if (array >= std::size(kNodeArrays)) {
    assign_bar_states(array - std::size(kNodeArrays), first, count, in);
    return;
  }
  SimulationCore& c = *core_;
  if (array < 3)
    c.forget_motion(first, count);
  UnsetVector<double>* u[6] = {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz};
  c.for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
    if (c.layout.stored(q)) // (an absent node stays at rest)
      std::copy(in, in + run, u[array]->begin() + static_cast<std::ptrdiff_t>(q));
    in += run;
  });
}

double Simulation::bar_state_value(std::size_t array, index_t bar) const {
  return core_->states[array][core_->layout.state_index(core_->lat, bar)];
}

std::span<double> Simulation::bar_state_array(std::size_t array) {
  // (By bar id: a layout of a law that counts cycles, whose material varies per bar; a compact
  // layout is of one material.)
  if (core_->layout.compact())
    throw std::logic_error("bar_state_array: the states of a compact layout are not by bar id");
  return core_->states[array];
}

Vec3 Simulation::platen_force(std::size_t p) const {
  return p < core_->bc.platens.size() ? core_->bc.platens[p].force : Vec3{};
}

Vec3 Simulation::platen_offset(std::size_t p) const {
  return p < core_->bc.platens.size() ? core_->bc.platens[p].offset : Vec3{};
}

std::size_t Simulation::platen_contacts(std::size_t p) const {
  return p < core_->bc.platens.size() ? core_->bc.platens[p].touches.size() : 0;
}

const std::array<ExactSum, 3>& Simulation::platen_force_sum(std::size_t p) const {
  static const std::array<ExactSum, 3> none{};
  return p < core_->bc.platens.size() ? core_->bc.platens[p].force_sum : none;
}

const ExactSum& Simulation::report_contact() const {
  return core_->bc.contact_energy;
}

void Simulation::set_platen_stiffness(double E_max, double rho_min) {
  const double L = core_->lat.L();
  for (Platen& p : core_->cond.platens)
    p.kappa = 4.0 * p.penalty * E_max / (rho_min * L * L);
}

std::vector<double> Simulation::platen_positions() const {
  std::vector<double> out;
  for (std::size_t p = 0; p < core_->cond.platens.size(); ++p) {
    const Vec3 a = platen_offset(p),
               b = p < core_->bc.platens.size() ? core_->bc.platens[p].previous : Vec3{};
    out.insert(out.end(), {a.x, a.y, a.z, b.x, b.y, b.z});
  }
  return out;
}

void Simulation::set_platen_positions(std::span<const double> positions) {
  std::vector<PlatenState>& platens = core_->bc.platens;
  platens.resize(core_->cond.platens.size());
  for (std::size_t p = 0; p < platens.size() && 6 * p + 5 < positions.size(); ++p) {
    const double* v = positions.data() + 6 * p;
    platens[p].offset = {v[0], v[1], v[2]};
    platens[p].previous = {v[3], v[4], v[5]};
  }
}

void Simulation::restore_progress(std::uint64_t step, const Ledger::State& ledger,
                                  const EnergyReport& report, std::vector<Event> pending) {
  SimulationCore& c = *core_;
  c.step = step;
  c.ledger.set_state(ledger);
  c.report = report;
  for (auto& ev : c.thread_events)
    ev.clear();
  c.thread_events[0] = std::move(pending);
  law_->mark_damaged_rows(c);
}

void Simulation::step(bool report) {
  SimulationCore& c = *core_;
  const double t = time();
  const bool energies = report || c.step == 0;
  if (!c.cond.platens.empty())
    apply_platens(c, t, energies);
  else if (!c.cond.loads.empty())
    apply_loads(c, t);
  // (The imposed nodes' v_{n-1/2}, for apply_velocities' work.)
  for (std::size_t v = 0; v < c.cond.velocities.size(); ++v) {
    const std::vector<std::size_t>& slots = c.bc.velocity_slots[v];
    std::vector<Vec3>& v_old = c.bc.imposed_v_old[v];
    for (std::size_t q = 0; q < slots.size(); ++q)
      v_old[q] = c.half_step_velocity(slots[q]);
  }
  const bool damped = c.opt.damping > 0.0,
             loads = !c.cond.loads.empty() || !c.cond.platens.empty();
  // A law with a fatigue life counts the strain at u_n (a distributed run's halo is current).
  if (law_->count_cycles)
    law_->count_cycles(c);
  // The law's walk, in the specialisation of the node update for this step.
  law_->advance(c, damped, loads, energies);
  apply_velocities(c, t, energies);
  const ExactSum platen_mid = c.cond.platens.empty() ? ExactSum{} : finish_platens(c, t);

  // The step's work and damping, row by row and DOF by DOF, added exactly (Ledger).
  // (Without damping or loads the rows' terms are zeros, which add nothing.)
  const std::size_t rows = c.layout.node_rows.size();
  // (Each row's term into an ExactAccumulator, then the conditions' sums: the same bits.)
  const auto rows_sum = [rows](ExactSum into, const std::vector<double>& terms, bool on) {
    ExactAccumulator a;
    for (std::size_t r = 0; on && r < rows; ++r)
      a.add(terms[r]);
    into.add(a.sum());
    return into;
  };
  const ExactSum damping = rows_sum(c.bc.damping, c.row_damping, damped);
  const ExactSum load_mid = rows_sum(c.bc.work, c.row_load_mid, loads);
  if (energies) {
    const ExactSum kinetic = rows_sum(c.bc.kinetic, c.row_kinetic, true),
                   work_half = rows_sum(c.bc.work_half, c.row_load_half, loads);
    // Damping: the part of this step's dissipation a dt v_n . m v_n that lies before t_n,
    // taken as half of it (the exact split a m v_n . dt v_{n-1/2} / 2 differs by O(dt^2)).
    const BarEnergies bars = law_->report_bar_energies(c);
    const double elastic = bars.elastic, damage = bars.damage;
    if (c.step == 0)
      c.ledger.set_initial(elastic + kinetic.value());
    c.report_work = c.ledger.state().work;
    c.report_work.add(work_half);
    if (!c.cond.platens.empty())
      c.report_work.add(c.bc.platen_half);
    c.report_damping2 = Ledger::twice_damping_at_report(c.ledger.state(), damping);
    c.report =
        energy_report(t, c.report_work.value(), elastic, kinetic.value(), damage,
                      0.5 * c.report_damping2.value(), c.ledger.initial(),
                      balance_floor(c.table.ranges().E[1], c.table.ranges().e_p[1], c.lat.volume()),
                      bars.fatigue, c.bc.contact_energy.value(),
                      c.ledger.state().friction.value());
  }
  c.ledger.work().add(load_mid);
  c.ledger.work().add(platen_mid);
  c.ledger.damping().add(damping);
  c.ux.swap(c.wx);
  c.uy.swap(c.wy);
  c.uz.swap(c.wz);
  ++c.step;
}

std::vector<Event> Simulation::take_events() {
  std::vector<Event> all;
  for (auto& ev : core_->thread_events) {
    all.insert(all.end(), ev.begin(), ev.end());
    ev.clear();
  }
  std::sort(all.begin(), all.end(), event_before);
  return all;
}

BarState Simulation::bar_state(index_t bar) const {
  return law_->bar_state(*core_, bar);
}

double Simulation::bar_force(index_t bar) const {
  return law_->bar_force(*core_, bar);
}

Vec3 Simulation::node_force(index_t node) const {
  return law_->node_force(*core_, node);
}

void Simulation::internal_forces(std::vector<double>& fx, std::vector<double>& fy,
                                 std::vector<double>& fz) const {
  law_->internal_forces(*core_, fx, fy, fz);
}

Simulation::BarEnergies Simulation::bar_energies() const {
  return law_->bar_energies(*core_);
}

double Simulation::stored_energy() const {
  return bar_energies().elastic;
}

void Simulation::bar_snapshot(std::vector<std::uint8_t>& state, std::vector<double>& damage,
                              std::vector<double>& force, std::vector<double>* strain) const {
  law_->bar_snapshot(*core_, state, damage, force, strain);
}

int Simulation::set_threads(int n) {
  SimulationCore& c = *core_;
  const auto built = static_cast<int>(c.thread_scratch.size());
  c.threads = std::clamp(n, 1, built);
  return c.threads;
}

int Simulation::threads() const {
  return core_->threads;
}

index_t Simulation::first_bad_node() const {
  const Lattice& lat = core_->lat;
  return first_node_beyond(1e3 * lat.L() *
                           static_cast<double>(std::max({lat.nx(), lat.ny(), lat.nz()})));
}

namespace {

// Over slots [q0, q1): the sum of |u| (which NaN and infinity make non-finite: a maximum may
// pass a NaN over) into s, and its largest component into top (a function of its own, every
// array a __restrict parameter, so that GCC 12 vectorises it).
[[gnu::noinline]] void add_motion_bounds(const double* __restrict ux, const double* __restrict uy,
                                         const double* __restrict uz, std::int64_t q0,
                                         std::int64_t q1, double& s, double& top) {
  double sum = 0.0, big = 0.0;
#pragma omp simd reduction(+ : sum) reduction(max : big)
  for (std::int64_t q = q0; q < q1; ++q) {
    const double ax = std::abs(ux[q]), ay = std::abs(uy[q]), az = std::abs(uz[q]);
    sum += ax + ay + az;
    big = std::max(big, std::max(ax, std::max(ay, az)));
  }
  s += sum;
  top = std::max(top, big);
}

} // namespace

index_t Simulation::first_node_beyond(double limit) const {
  const SimulationCore& c = *core_;
  const index_t nn = c.lat.num_nodes();
  // A quick test of the whole field first, shared by the threads: its largest component (the
  // slots between rows hold zeros) and its sum, finite unless a NaN or an infinity is there.
  // The sum's order, which the thread count changes, decides only whether the node by node
  // look below is needed, and that look gives the answer. (A bound by the sum alone sent any
  // body whose motions add up past the limit, the usual case for time.stop_displacement,
  // through that serial look at every test.)
  double s = 0.0, top = 0.0;
  const auto slots = static_cast<std::int64_t>(c.layout.slot_count);
  constexpr std::int64_t kBlock = 4096;
#pragma omp parallel for schedule(static) reduction(+ : s) reduction(max : top) \
    if (slots > kParallelMinItems)
  for (std::int64_t q = 0; q < slots; q += kBlock)
    add_motion_bounds(c.ux.data(), c.uy.data(), c.uz.data(), q, std::min(slots, q + kBlock), s,
                      top);
  if (std::isfinite(s) && top <= limit)
    return nn;
  for (index_t n = 0; n < nn; ++n) {
    const std::size_t q = c.slot(n);
    if (!(std::abs(c.ux[q]) <= limit && std::abs(c.uy[q]) <= limit && std::abs(c.uz[q]) <= limit))
      return n;
  }
  return nn;
}

std::vector<double> Simulation::masses() const {
  const SimulationCore& c = *core_;
  std::vector<double> m(c.lat.num_nodes());
  c.for_each_run(0, c.lat.num_nodes(), [&](std::size_t q, index_t n, index_t run) {
    std::copy(c.mass.begin() + q, c.mass.begin() + q + run, m.begin() + n);
  });
  return m;
}

std::vector<DofMask> Simulation::held_dofs() const {
  const SimulationCore& c = *core_;
  std::vector<DofMask> h(c.lat.num_nodes());
  c.for_each_run(0, c.lat.num_nodes(), [&](std::size_t q, index_t n, index_t run) {
    std::copy(c.held.begin() + q, c.held.begin() + q + run, h.begin() + n);
  });
  return h;
}

std::uint64_t Simulation::broken_count() const {
  std::uint64_t n = 0;
  for (index_t b = 0; b < core_->lat.num_bars(); ++b)
    n += bar_state(b) == BarState::Broken;
  return n;
}

std::uint64_t Simulation::softening_count() const {
  std::uint64_t n = 0;
  for (index_t b = 0; b < core_->lat.num_bars(); ++b)
    n += bar_state(b) == BarState::Softening;
  return n;
}

double Simulation::bytes_per_module() const {
  const SimulationCore& c = *core_;
  const StepLayout& l = c.layout;
  auto bytes = [](const auto& v) { return static_cast<double>(v.size() * sizeof(v[0])); };
  double total = 0.0;
  for (const auto* v : {&c.ux, &c.uy, &c.uz, &c.wx, &c.wy, &c.wz, &c.px, &c.py, &c.pz})
    total += bytes(*v);
  total += bytes(c.mass) + bytes(c.inv_mass);
  for (const auto& s : c.states)
    total += bytes(s);
  total += bytes(c.held);
  for (const auto& q : c.bc.velocity_slots)
    total += bytes(q);
  for (const auto& q : c.bc.imposed_force_at)
    total += bytes(q);
  total += bytes(c.bc.imposed_row) + bytes(c.bc.imposed_force);
  for (const auto& q : c.bc.load_slots)
    total += bytes(q);
  for (const NodalLoad& load : c.cond.loads)
    total += bytes(load.weight);
  total += bytes(l.link_ref) + bytes(l.row_kind) + bytes(l.link_const) + bytes(l.row_kinds) +
           bytes(c.row_held) + bytes(c.damaged_span) + bytes(l.node_rows) + bytes(l.bar_rows) +
           bytes(c.row_fast) + bytes(c.line_fast) + bytes(c.row_ratio) + bytes(l.row_inv_lp) +
           bytes(l.row_first_centre) + bytes(l.row_whole) + bytes(l.bar_row_nodes) +
           bytes(c.node_row_motion) + bytes(l.edge_lanes) + bytes(l.bar_code) + bytes(l.row_span) +
           bytes(l.row_origin) + bytes(l.row_window) + bytes(l.state_origin) +
           bytes(l.code_origin) + bytes(l.bar_row_at);
  for (const auto& b : c.plane_buffers)
    total += bytes(b);
  for (const auto& b : c.line_stores)
    total += bytes(b);
  if (c.table.per_bar())
    total += bytes(c.table.k_bar()) + bytes(c.table.e_p_bar()) + bytes(c.table.e_r_bar());
  return total / static_cast<double>(c.lat.num_present_modules());
}

} // namespace ldem
