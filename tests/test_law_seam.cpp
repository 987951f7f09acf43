// The seam for bar laws (solver/law_kernels.hpp): a second law, defined here and not in the
// library, runs through the same kernels as the paper's bilinear law (the intact kernel, the
// general kernel, the slow path, the report energies, the snapshots), and its forces are
// minus the gradient of its energy.
#include "app/run_body.hpp"
#include "helpers.hpp"
#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "solver/law_kernels.hpp"
#include "solver/laws.hpp"

#include <cstring>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <limits>
#include <random>

namespace ldem {
namespace {

using testing::all_state;
using testing::make_sim;
using testing::unit_material;

// Linear elastic without failure: F = k (l - l0) at any strain, so the stored energy is
// U = k (l - l0)^2 / 2 per bar and nothing is dissipated. Its state, "peak_strain", is the
// largest strain the bar has reached beyond a watch strain e_w (the family's e_p): the bar is
// pristine until its strain first passes e_w, after which the general kernel takes it and the
// slow path records its peaks. The state changes no force.
struct RecordingElasticLaw {
  double e_w;

  static constexpr std::string_view kName = "recording_elastic";
  static constexpr std::array<StateArray, 1> kStateArrays{{{"peak_strain", true}}};
  struct State {
    double peak;
  };
  static State read(const double* const* arrays, std::int64_t i) noexcept { return {arrays[0][i]}; }
  static void write(double* const* arrays, std::int64_t i, State s) noexcept {
    arrays[0][i] = s.peak;
  }
  State initial() const noexcept { return {e_w}; }
  static State precracked() noexcept { return {std::numeric_limits<double>::infinity()}; }
  bool pristine(State s) const noexcept { return s.peak == e_w; }
  double elastic_limit() const noexcept { return e_w; }
  static double force_over_length(double k, Stretch g, State) noexcept { return k * g.dl / g.l; }
  static bool changes(double e, State s) noexcept { return e > s.peak; }
  template <class Emit> static void update(double e, State& s, Emit&&) { s.peak = e; }
  static double elastic_energy(double s_over_l, Stretch g, State) noexcept {
    return 0.5 * s_over_l * g.l * g.dl;
  }
  static double dissipated_energy(double, double, State) noexcept { return 0.0; }
  static double damage(double, double, State) noexcept { return 0.0; }
  static BarState state(State) noexcept { return BarState::Intact; }

  struct Row;
  static Row row(const BarTable& table, int family, index_t first_bar);
  template <bool PerBar> static RecordingElasticLaw at(const Row& row, std::int64_t i) noexcept;
};
struct RecordingElasticLaw::Row {
  RecordingElasticLaw family;
};
RecordingElasticLaw::Row RecordingElasticLaw::row(const BarTable& table, int family, index_t) {
  return {{table.family(family).e_p}};
}
template <bool PerBar>
RecordingElasticLaw RecordingElasticLaw::at(const Row& row, std::int64_t) noexcept {
  return row.family;
}
static_assert(BarLaw<RecordingElasticLaw>);

// A 3 x 3 x 3 body of the recording law (a uniform material, or one whose E is given per bar,
// which takes the per-bar kernels), e_w = 0.02.
Simulation recording_body(bool per_bar) {
  SolverOptions o;
  o.law = &law_kernels<RecordingElasticLaw>();
  const MaterialSpec m = unit_material(0.02, 4.0);
  BarFields fields;
  if (per_bar)
    fields.E.assign(Lattice(3, 3, 3, 1.0).num_bars(), m.E);
  return make_sim(3, 3, 3, 1.0, m, {}, o, {}, fields);
}

// The strain of bar `bar` at u_n, by the code's one formula (bar_law.hpp).
double strain_of(const Simulation& sim, index_t bar) {
  const Lattice& lat = sim.lattice();
  const auto [a, b] = lat.bar_nodes(bar);
  const FamilyInfo& fi = lat.family(lat.bar_address(bar).family);
  const Vec3 ua = sim.displacement(a), ub = sim.displacement(b);
  return stretch(fi.d0.x + (ub.x - ua.x), fi.d0.y + (ub.y - ua.y), fi.d0.z + (ub.z - ua.z), fi.l0,
                 1.0 / fi.l0)
      .e;
}

// Through the step's kernels the forces are minus the gradient of U = sum k (l - l0)^2 / 2,
// by central finite differences of the law's stored energy (error O(h^2), about 1e-10
// relative; the bound 1e-7 fmax, as for the bilinear law in test_elastic.cpp). The step
// recovers them from v_{1/2} = dt f / m from rest, to round-off (1e-9 fmax). Displacements of
// up to 0.05 L strain some bars past e_w = 0.02 and leave others below it, so the first step
// takes pristine rows through the intact kernel and the others through the general kernel and
// the slow path; the second step, from the same displacements, takes the rows the first
// marked through the general kernel with their recorded states.
TEST(LawSeam, ForcesThroughTheKernelsAreMinusTheEnergyGradient) {
  for (bool per_bar : {false, true}) {
    SCOPED_TRACE(per_bar ? "per-bar kernels" : "uniform material");
    Simulation sim = recording_body(per_bar);
    ASSERT_EQ(sim.law_name(), "recording_elastic");
    ASSERT_EQ(sim.table().per_bar(), per_bar);
    const Lattice& lat = sim.lattice();
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-0.05, 0.05);
    std::vector<Vec3> u0(lat.num_nodes());
    for (index_t n = 0; n < lat.num_nodes(); ++n)
      u0[n] = {u(rng), u(rng), u(rng)};
    const auto place = [&] {
      for (index_t n = 0; n < lat.num_nodes(); ++n) {
        sim.set_displacement(n, u0[n]);
        sim.set_half_step_velocity(n, {0, 0, 0});
      }
    };
    place();
    // Minus the energy gradient, and the exact energy.
    const std::vector<Vec3> grad = testing::minus_energy_gradient(sim, 1e-6);
    double fmax = 0.0;
    for (const Vec3& f : grad)
      fmax = std::max({fmax, std::abs(f.x), std::abs(f.y), std::abs(f.z)});
    double U = 0.0;
    for (index_t b = 0; b < lat.num_bars(); ++b) {
      const double e = strain_of(sim, b), l0 = lat.family(lat.bar_address(b).family).l0;
      U += 0.5 * sim.table().stiffness(lat, b) * (e * l0) * (e * l0);
    }
    EXPECT_NEAR(sim.stored_energy(), U, 1e-12 * U);
    ASSERT_GT(fmax, 0.0);
    int above = 0; // bars strained past e_w
    for (index_t b = 0; b < lat.num_bars(); ++b)
      above += strain_of(sim, b) > 0.02;
    ASSERT_GT(above, 10);
    ASSERT_LT(above, static_cast<int>(lat.num_bars()) - 10);
    for (int pass = 0; pass < 2; ++pass) {
      SCOPED_TRACE(pass == 0 ? "first step" : "second step");
      place();
      sim.step(true);
      // A report step's elastic energy from the kernels: the same U.
      EXPECT_NEAR(sim.last_report().elastic, U, 1e-12 * U);
      EXPECT_EQ(sim.last_report().damage_dissipated, 0.0);
      for (index_t n = 0; n < lat.num_nodes(); ++n) {
        const Vec3 v = sim.half_step_velocity(n);
        const double k = sim.mass(n) / sim.dt();
        EXPECT_NEAR(v.x * k, grad[n].x, 1e-7 * fmax) << "node " << n;
        EXPECT_NEAR(v.y * k, grad[n].y, 1e-7 * fmax) << "node " << n;
        EXPECT_NEAR(v.z * k, grad[n].z, 1e-7 * fmax) << "node " << n;
      }
    }
    // The slow path recorded, for every bar strained past e_w, the strain it was strained to
    // (the same number: the kernels and the slow path take the one formula), and left the
    // others at e_w.
    place();
    for (index_t b = 0; b < lat.num_bars(); ++b) {
      const double e = strain_of(sim, b);
      EXPECT_EQ(sim.bar_state_value(0, b), e > 0.02 ? e : 0.02) << "bar " << b;
    }
    EXPECT_EQ(sim.broken_count(), 0u);
    EXPECT_EQ(sim.softening_count(), 0u);
  }
}

// A free body of the law, shaken by random initial velocities, keeps its energy: central
// differences conserve H = 1/2 v_{n-1/2} M v_{n+1/2} + U(u_n) exactly for a linear system (the
// report's kinetic energy is that cross product, docs/model.md), and at strains of about 1e-6
// the lattice is linear to about 1e-6, so H may drift by less than 1e-5 relative over 2000
// steps (as in test_elastic.cpp's UndampedVibrationConservesEnergy, at 1e-7 and 1e-6). With
// e_w = 2e-7 most bars pass it and go through the general kernel and the slow path, which
// records their peaks; nothing is dissipated and no event is raised.
TEST(LawSeam, ElasticLawConservesEnergyThroughTheKernels) {
  SolverOptions o;
  o.law = &law_kernels<RecordingElasticLaw>();
  Simulation sim = make_sim(3, 2, 4, 1.0, unit_material(2e-7, 4.0), {}, o);
  const Lattice& lat = sim.lattice();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1e-6, 1e-6);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    sim.set_half_step_velocity(n, {u(rng), u(rng), u(rng)});
  double h_max_dev = 0.0, h0 = 0.0;
  for (int s = 0; s < 2000; ++s) {
    sim.step(true);
    const EnergyReport& r = sim.last_report();
    if (s == 0)
      h0 = r.initial;
    h_max_dev = std::max(h_max_dev, std::abs(r.elastic + r.kinetic - h0));
    EXPECT_EQ(r.damage_dissipated, 0.0);
  }
  ASSERT_GT(h0, 0.0);
  EXPECT_LT(h_max_dev / h0, 1e-5);
  EXPECT_TRUE(sim.take_events().empty());
  int recorded = 0;
  for (index_t b = 0; b < lat.num_bars(); ++b)
    recorded += sim.bar_state_value(0, b) > 2e-7;
  EXPECT_GT(recorded, static_cast<int>(lat.num_bars()) / 4);
}

// A case for the run layer of the 3 x 2 x 4 body of the test above, of law `law`, shaken at
// strains of about 1e-3, past e_w = 2e-4 in many bars.
BuiltCase recording_case(const LawKernels& law) {
  BuiltCase c;
  c.path = "recording.toml";
  SolverOptions o;
  o.law = &law;
  c.lattice.emplace(3, 2, 4, 1.0);
  c.sim = std::make_unique<Simulation>(make_sim(3, 2, 4, 1.0, unit_material(2e-4, 4.0), {}, o));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1e-3, 1e-3);
  for (index_t n = 0; n < c.lattice->num_nodes(); ++n)
    c.sim->set_half_step_velocity(n, {u(rng), u(rng), u(rng)});
  return c;
}

// A law's state, declared once in its kStateArrays, is saved by name without any code of the
// checkpoint or the snapshots knowing the law: a checkpoint lists the recording law's
// "peak_strain" among its arrays and a run resumed from it continues bit for bit as the run
// that went on; a VTU snapshot carries "peak_strain" per bar, each value the state's in single
// precision. A body of another law refuses the checkpoint, naming both laws.
TEST(LawSeam, StateIsCheckpointedAndSnapshottedByName) {
  const std::string dir = ::testing::TempDir() + "ldem_law_seam";
  std::filesystem::create_directories(dir);
  const std::string ckpt = dir + "/state.ckpt", vtu = dir + "/snapshot.vtu";
  const LawKernels& law = law_kernels<RecordingElasticLaw>();
  BuiltCase a = recording_case(law);
  std::unique_ptr<RunBody> body = make_serial_body(a);
  for (int s = 0; s < 40; ++s)
    body->step(s % 10 == 0);
  body->write_checkpoint(ckpt, "meta");
  body->write_snapshot(vtu);
  const checkpoint::Header h = checkpoint::read_header(ckpt);
  const checkpoint::Progress p = checkpoint::read_progress(h, ckpt);
  EXPECT_EQ(p.law, "recording_elastic");
  ASSERT_EQ(p.arrays.size(), 7u);
  EXPECT_EQ(p.arrays[6].name, "peak_strain");
  EXPECT_TRUE(p.arrays[6].per_bar);
  const std::vector<double> peak = all_state(*a.sim)[6];
  int recorded = 0;
  for (double x : peak)
    recorded += x > 2e-4;
  ASSERT_GT(recorded, 20);

  // The snapshot's "peak_strain" array: its values follow its byte count in the appended data.
  const VtuLayout layout = vtu_layout(a.lattice->num_nodes(), a.lattice->num_bars(), *a.sim);
  ASSERT_EQ(layout.states.size(), 1u);
  std::ifstream in(vtu, std::ios::binary);
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(file.find("Name=\"peak_strain\""), std::string::npos);
  ASSERT_EQ(file.size(), layout.size);
  for (index_t b = 0; b < a.lattice->num_bars(); ++b) {
    float v = 0.0f;
    std::memcpy(&v, file.data() + layout.state_value_at(0, b), sizeof v);
    ASSERT_EQ(v, static_cast<float>(peak[b])) << "bar " << b;
  }

  // Resumed against continued: the same bits.
  for (int s = 40; s < 80; ++s)
    body->step(s % 10 == 0);
  BuiltCase b = recording_case(law);
  std::unique_ptr<RunBody> resumed = make_serial_body(b);
  EXPECT_EQ(resumed->read_checkpoint(ckpt), "meta");
  EXPECT_EQ(b.sim->step_count(), 40u);
  for (int s = 40; s < 80; ++s)
    resumed->step(s % 10 == 0);
  EXPECT_EQ(all_state(*a.sim), all_state(*b.sim));

  // The bilinear law's body has the same counts and dt, but not the same law.
  BuiltCase c = recording_case(default_law());
  std::unique_ptr<RunBody> other = make_serial_body(c);
  try {
    other->read_checkpoint(ckpt);
    ADD_FAILURE() << "a checkpoint of another bar law was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bar law \"recording_elastic\""), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("\"bilinear\""), std::string::npos) << e.what();
  }
}

} // namespace
} // namespace ldem
