// Rigid platens ([[platen]]): penalty contact with Coulomb friction (docs/model.md, "Platens").
// Blocks of 10 mm modules, E = 30 GPa, rho = 2400 kg/m^3 (strong enough to stay elastic),
// resting, pressed, sliding and falling on planes and rollers.
#include "app/case_run.hpp"
#include "app/run_loop.hpp"
#include "csv_columns.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace ldem {
namespace {

constexpr double kE = 30.0e9, kRho = 2400.0, kL = 0.01;

// A box of nx x ny x nz modules of kL with `rest` (its conditions and platens) after it.
std::string block(int nx, int ny, int nz, const std::string& rest) {
  std::ostringstream s;
  s << "[lattice]\nmodules = [" << nx << ", " << ny << ", " << nz << "]\nL = " << kL
    << "\n[material]\nE = " << kE << "\nrho = " << kRho
    << "\nGf = 1.0e4\ne_p = 1.0e-3\n[output]\nenergy_every = 50\nvtu = false\nplots = false\n"
    << rest;
  return s.str();
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("ldem_platen_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

BuiltCase built(const std::string& text, const std::string& name) {
  const fs::path path = fresh_dir(name) / "case.toml";
  std::ofstream(path) << text;
  return build_case(path.string());
}

// Steps a built case to its end time.
void run_to_end(BuiltCase& c) {
  const auto steps = run_steps(c.spec.end_time, c.sim->dt());
  for (std::uint64_t n = 0; n < steps; ++n)
    c.sim->step();
}

// The body's centre of mass displacement.
Vec3 mean_displacement(const Simulation& sim) {
  double m = 0.0, x = 0.0, y = 0.0, z = 0.0;
  for (index_t n = 0; n < sim.lattice().num_nodes(); ++n) {
    const Vec3 u = sim.displacement(n);
    m += sim.mass(n);
    x += sim.mass(n) * u.x, y += sim.mass(n) * u.y, z += sim.mass(n) * u.z;
  }
  return {x / m, y / m, z / m};
}

const char* kGravity = R"(
[[node_set]]
name = "all"
all = true
[[load]]
name = "g"
set = "all"
acceleration = [0.0, 0.0, -1.0e4]
)";

TEST(Platen, ABlockRestingOnAPlaneOrOnTwoRollersWeighsOnThem) {
  // At rest (the ringing damped as exp(-a t / 2) = exp(-20)) a platen carries the weight
  // rho V g: 2400 * 0.04^3 * 1e4 = 1536 N on the plane. A beam of 12 x 2 x 3 modules on two
  // rollers 80 mm apart, symmetric about its middle, puts half of its 3456 N on each.
  BuiltCase plane = built(block(4, 4, 4, std::string(kGravity) + R"(
[[platen]]
name = "floor"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 2.0]
[time]
end = 4.0e-4
damping = 1.0e5
)"),
                          "rest");
  run_to_end(plane);
  const double weight = kRho * std::pow(4 * kL, 3) * 1.0e4;
  EXPECT_NEAR(plane.sim->platen_force(0).z, weight, 1e-6 * weight);
  EXPECT_NEAR(plane.sim->platen_force(0).x, 0.0, 1e-9 * weight);
  // Every node of the base touches (its 25 corner nodes), each pushed by k_i d_i with
  // k_i = kappa m_i: so the base's mass-weighted mean sinking, sum m_i d_i / sum m_i, is the
  // weight over the springs' sum kappa sum m_i = E A / L = 4.8e9 N/m (k = E L on a face
  // node): 0.32 um.
  EXPECT_EQ(plane.sim->platen_contacts(0), 25u);
  double m = 0.0, md = 0.0;
  for (index_t n = 0; n < plane.sim->lattice().num_nodes(); ++n)
    if (plane.sim->lattice().position(n).z == 0.0) {
      m += plane.sim->mass(n);
      md -= plane.sim->mass(n) * plane.sim->displacement(n).z;
    }
  EXPECT_NEAR(md / m, weight / (kE * 16 * kL), 1e-6 * weight / (kE * 16 * kL));

  BuiltCase rollers = built(block(12, 2, 3, std::string(kGravity) + R"(
[[platen]]
name = "left"
shape = "cylinder"
point = [0.02, 0.0, -0.01]
axis = [0.0, 1.0, 0.0]
radius = 0.01
[[platen]]
name = "right"
shape = "cylinder"
point = [0.10, 0.0, -0.01]
axis = [0.0, -1.0, 0.0]
radius = 0.01
[time]
end = 2.0e-3
damping = 2.0e4
)"),
                            "rollers");
  run_to_end(rollers);
  const double beam = kRho * 12 * 2 * 3 * std::pow(kL, 3) * 1.0e4;
  EXPECT_NEAR(rollers.sim->platen_force(0).z, 0.5 * beam, 1e-5 * beam);
  EXPECT_NEAR(rollers.sim->platen_force(1).z, 0.5 * beam, 1e-5 * beam);
  // The rollers push along their radii, which the beam's turning at its supports tilts: x
  // forces, equal and opposite (nothing else pushes the beam along x; mirror symmetry).
  EXPECT_NEAR(rollers.sim->platen_force(0).x + rollers.sim->platen_force(1).x, 0.0, 1e-9 * beam);
  EXPECT_LT(std::abs(rollers.sim->platen_force(0).x), 1e-3 * beam);
  EXPECT_GE(rollers.sim->platen_contacts(0), 3u); // the line of nodes on top of the roller
}

// A column of 4 x 4 x 8 modules between two frictionless platens, or with its faces driven as
// rollers (z imposed, x and y free), the top pushed down by 20 um and held, damped to rest.
std::string column(const std::string& penalty, const std::string& friction = "0.0") {
  return block(4, 4, 8, R"(
[[platen]]
name = "bottom"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
penalty = )" + penalty + "\nfriction = " + friction + R"(
[[platen]]
name = "top"
point = [0.0, 0.0, 0.08]
normal = [0.0, 0.0, -1.0]
velocity = [0.0, 0.0, -0.1]
function = [{ type = "table", points = [[0.0, 0.0], [1.0e-4, 1.0], [2.0e-4, 1.0], [3.0e-4, 0.0]] }]
penalty = )" + penalty + "\nfriction = " + friction + R"(
[time]
end = 1.0e-3
damping = 3.0e4
)");
}

const char* kRollerColumn = R"(
[[node_set]]
name = "bottom"
face = "z-"
[[node_set]]
name = "top"
face = "z+"
[[fixed]]
set = "bottom"
dofs = "z"
[[velocity]]
set = "top"
dofs = "z"
value = [0.0, 0.0, -0.1]
function = [{ type = "table", points = [[0.0, 0.0], [1.0e-4, 1.0], [2.0e-4, 1.0], [3.0e-4, 0.0]] }]
[time]
end = 1.0e-3
damping = 3.0e4
)";

TEST(Platen, AFrictionlessPlatenPressesABlockAsRollersInSeriesWithItsSprings) {
  // Rollers: stiffness K_v = F_v / d, face forces f_i (the top face's static reactions; the
  // bottom face's are the same by symmetry).
  BuiltCase rol = built(block(4, 4, 8, kRollerColumn), "rollers_column");
  run_to_end(rol);
  const Simulation& rs = *rol.sim;
  const Lattice& lat = rs.lattice();
  double F_v = 0.0, f2_over_m = 0.0, face_mass = 0.0, d = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    if (std::abs(lat.position(n).z - 8 * kL) < 1e-9) {
      const double f = rs.node_force(n).z; // the bars' force; the rollers' reaction is -f
      F_v += f;
      f2_over_m += f * f / rs.mass(n);
      face_mass += rs.mass(n);
      d = -rs.displacement(n).z;
    }
  ASSERT_GT(F_v, 0.0);
  EXPECT_NEAR(d, 2.0e-5, 1e-8); // the table's area: 0.1 m/s over 0.2 ms
  const double C_v = d / F_v;
  for (const double penalty : {1.0, 10.0}) {
    BuiltCase pl = built(column(std::to_string(penalty)), "platen_column");
    run_to_end(pl);
    const double F = -pl.sim->platen_force(1).z, D = -pl.sim->platen_offset(1).z;
    EXPECT_NEAR(D, 2.0e-5, 1e-8);
    EXPECT_NEAR(pl.sim->platen_force(0).z, F, 1e-5 * F); // at rest: the two forces balance
    // The springs k_i = kappa m_i, kappa = 4 penalty E / (rho L^2). Quasi-static, linear:
    // - potential energy, the rollers' body with both faces' springs compressed evenly (a
    //   kinematically admissible field): the compliance C = D / F is at least
    //   C_v + 2 / sum k_i, and sum k_i over a face = penalty E A / L;
    // - complementary energy, the rollers' forces f_i carried by the springs (a statically
    //   admissible field): C is at most C_v + 2 sum (f_i^2 / k_i) / F_v^2.
    const double kappa = 4.0 * penalty * kE / (kRho * kL * kL);
    const double lower = C_v + 2.0 / (kappa * face_mass);
    const double upper = C_v + 2.0 * f2_over_m / (kappa * F_v * F_v);
    EXPECT_NEAR(kappa * face_mass, penalty * kE * 16 * kL * kL / kL, 1e-6 * kappa * face_mass);
    const double C = D / F;
    EXPECT_GE(C, lower * (1.0 - 1e-5)) << "penalty " << penalty;
    EXPECT_LE(C, upper * (1.0 + 1e-5)) << "penalty " << penalty;
    EXPECT_GT(upper - lower, 0.0);
  }
}

TEST(Platen, FrictionHoldsTheEndsOfAPressedColumn) {
  // The coarsened form of docs/validation/compression.md, elastic: the column above pressed by
  // 20 um between platens without friction and with mu = 0.5. Without friction its ends expand
  // sideways freely: at mid-height by nu e_z, and at the ends more (1.9 against 1.0 um here),
  // the lattice's face layer (docs/model.md, section 2: its diagonals push the face's nodes
  // outwards where no centre-centre bar beyond the face holds them). With friction the
  // platens hold the ends (the shear they need, of order nu sigma, is below mu sigma): they
  // expand less than half as much, and the column, held at its ends, is stiffer (the held ends
  // are a constraint the free ones lack).
  struct Result {
    double end, middle, force;
  };
  const auto press = [](const char* friction) {
    BuiltCase c = built(column("1.0", friction), std::string("ends_") + friction);
    run_to_end(c);
    // The mean x displacement of the nodes of the face x = 4 L, at the top and at mid-height.
    double end = 0.0, middle = 0.0;
    int n_end = 0, n_middle = 0;
    const Lattice& lat = c.sim->lattice();
    for (index_t n = 0; n < lat.num_nodes(); ++n) {
      const Vec3 X = lat.position(n);
      if (std::abs(X.x - 4 * kL) > 1e-9)
        continue;
      if (std::abs(X.z - 8 * kL) < 1e-9)
        end += c.sim->displacement(n).x, ++n_end;
      if (std::abs(X.z - 4 * kL) < 1e-9)
        middle += c.sim->displacement(n).x, ++n_middle;
    }
    return Result{end / n_end, middle / n_middle, -c.sim->platen_force(1).z};
  };
  const Result free = press("0.0"), held = press("0.5");
  // The lateral strain at mid-height, nu times the axial strain (2e-5 / 0.08 less the springs'
  // share, 0.22e-3), 0.25 * 0.22e-3 * 0.02 m = 1.1 um from the axis to the face.
  EXPECT_GT(free.middle, 0.8e-6);
  EXPECT_LT(free.middle, 1.4e-6);
  EXPECT_GT(free.end, free.middle);
  EXPECT_LT(held.end, 0.5 * free.end);
  EXPECT_GT(held.middle, 0.8 * free.middle);
  EXPECT_GT(held.force, free.force);
}

TEST(Platen, FrictionlessPlatensSplitAPrismWhereFrictionalOnesHoldIt) {
  // The coarsened form of docs/validation/compression.md to failure: a prism of 8 x 8 x 16
  // modules of 2.5 mm (E = 50 GPa, e_p = 2e-4, Gf = 50 N/m) shortened at 20 mm/s by 2e-3 of its
  // height. Between frictionless platens it expands freely, e_lat = nu e_z, and its bars across
  // the load reach their peak strain e_p when sigma = E e_p / nu = 40 MPa (nu = 0.25): it splits
  // along the load and, nothing holding the split columns together, the load falls to nothing.
  // 10 %: the lattice's free faces (its uniaxial modulus on a finite section is below E) and
  // the bars' softening before the peak. With friction 0.3 the platens hold the columns' ends:
  // the bars never fail in compression, and the load is still at its peak at the end, past twice
  // that (the paper's law has no compressive or shear failure; docs/validation/compression.md).
  const auto curve = [](const char* friction) {
    std::string text = block(8, 8, 16, std::string(R"(
[[platen]]
name = "lower"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
friction = )") + friction + R"(
[[platen]]
name = "upper"
point = [0.0, 0.0, 0.04]
normal = [0.0, 0.0, -1.0]
velocity = [0.0, 0.0, -0.02]
ramp = 5.0e-4
friction = )" + friction + R"(
[time]
end = 4.5e-3
damping = 4000.0
[[probe]]
name = "load"
kind = "platen"
platen = "upper"
)");
    text.replace(text.find("L = 0.01"), 8, "L = 0.0025");
    text.replace(text.find("E = 3e+10"), 9, "E = 5e+10");
    text.replace(text.find("Gf = 1.0e4\ne_p = 1.0e-3"), 23, "Gf = 50.0\ne_p = 2.0e-4");
    const fs::path dir = fresh_dir(std::string("split_") + friction);
    std::ofstream(dir / "case.toml") << text;
    RunOptions o;
    o.plots = false;
    o.out_dir = (dir / "out").string();
    EXPECT_EQ(run_command((dir / "case.toml").string(), o), 0);
    std::vector<double> stress;
    const auto columns = testing::csv_columns(dir / "out" / "probes.csv");
    for (double f : columns.at("load"))
      stress.push_back(-f / (0.02 * 0.02)); // Pa over the 20 x 20 mm section
    fs::remove_all(dir);
    return stress;
  };
  const double expected = 50.0e9 * 2.0e-4 / 0.25;
  const std::vector<double> free = curve("0.0"), held = curve("0.3");
  ASSERT_GT(free.size(), 10u);
  const double peak = *std::max_element(free.begin(), free.end());
  EXPECT_NEAR(peak, expected, 0.1 * expected);
  EXPECT_LT(free.back(), 0.05 * peak);
  // Held: the load carries its peak to the end (a split prism keeps under 5 % of its own), to
  // the wobble of the bars that still break inside (0.04 % at the last sample, 1,755 of them
  // broken by then).
  EXPECT_GT(held.back(), 0.99 * *std::max_element(held.begin(), held.end()));
  EXPECT_GT(held.back(), 1.5 * expected);
}

TEST(Platen, TheStableStepMakesRoomForTheSprings) {
  // omega_max^2 grows by the sum of the platens' kappa (Weyl's inequality): two platens of
  // penalty 1, 2 * 4 E / (rho L^2).
  BuiltCase rol = built(block(4, 4, 8, kRollerColumn), "stable_rollers");
  BuiltCase pl = built(column("1.0"), "stable_platens");
  // (The rollers' held DOF remove modes; the free column's omega_max is the same or higher.)
  const Simulation free_column(Lattice(4, 4, 8, kL), pl.sim->table(), Conditions{},
                               pl.options);
  const double w0 = free_column.stable_step().omega_max, w = pl.sim->stable_step().omega_max;
  EXPECT_NEAR(w * w, w0 * w0 + 8.0 * kE / (kRho * kL * kL), 1e-12 * w * w);
  EXPECT_NEAR(pl.sim->stable_step().dt, 2.0 / w, 1e-15);
  EXPECT_LT(pl.sim->dt(), rol.sim->dt());
}

// A block of 4 x 4 x 4 on a platen of friction 0.5 under a body force that pulls it down with
// g = 1e4 m/s^2 and along x with `along`, both ramped over 0.1 ms; no damping.
std::string tilted(double along, const std::string& end) {
  std::ostringstream s;
  s << R"(
[[node_set]]
name = "all"
all = true
[[load]]
name = "g"
set = "all"
acceleration = [)"
    << along << R"(, 0.0, -1.0e4]
function = [{ type = "ramp", duration = 1.0e-4 }]
[[platen]]
name = "floor"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
friction = 0.5
[time]
end = )" << end
    << R"(
[[probe]]
name = "fx"
kind = "platen"
platen = "floor"
component = "x"
[[probe]]
name = "fz"
kind = "platen"
platen = "floor"
[[probe]]
name = "x"
kind = "displacement"
set = "all"
component = "x"
)";
  return block(4, 4, 4, s.str());
}

TEST(Platen, FrictionHoldsBelowMuNAndSlidesAtTheRestOfTheForceAbove) {
  const double mu = 0.5, g = 1.0e4, T = 1.0e-4;
  for (const double along : {0.25 * g, 1.0 * g}) {
    BuiltCase c = built(tilted(along, "1.0e-3"), "slide");
    const auto steps = run_steps(c.spec.end_time, c.sim->dt());
    double slid = 0.0, work = 0.0; // the centre's motion, and mu F_z along it
    Vec3 last{};
    for (std::uint64_t n = 0; n < steps; ++n) {
      c.sim->step(n + 1 == steps);
      const Vec3 F = c.sim->platen_force(0);
      // Coulomb, node by node, so for the sum too: |F_t| <= mu F_n.
      ASSERT_LE(std::abs(F.x), mu * F.z * (1.0 + 1e-12) + 1e-12) << "step " << n;
      const Vec3 now = mean_displacement(*c.sim);
      slid += now.x - last.x;
      work += mu * F.z * (now.x - last.x);
      last = now;
    }
    const double t = c.sim->time();
    if (along < mu * g) {
      // It sticks: the centre moves only by the springs' stretch and the block's shear under
      // m a_t = 384 N: 384 N over springs adding to E A / L = 4.8e9 N/m, 0.08 um, and a shear
      // strain 384 N / A / G = 2e-5 (G = E / 2.5) over half the height, 0.4 um; twice that for
      // the ringing (no damping): 1 um, against the 2 mm it slides at a_t = g.
      EXPECT_LT(std::abs(last.x), 1e-6);
    } else {
      // It slides at a = along - mu g, ramped in over T: x(t) = a (t^2 / 2 - T t / 2 + T^2 / 6)
      // for t > T. The block rings (no damping) and the normal force with it, which moves the
      // mean only at second order: 1 %.
      const double a = along - mu * g;
      const double x = a * (t * t / 2 - T * t / 2 + T * T / 6);
      EXPECT_NEAR(last.x, x, 0.01 * x);
      // Every touching node slides: F_x = -mu F_z.
      const Vec3 F = c.sim->platen_force(0);
      EXPECT_NEAR(F.x, -mu * F.z, 1e-3 * mu * F.z);
      // The dissipation is mu N times the slip: to the same 1 % (the centre's slip against the
      // nodes' own, which differ by the block's elastic shear).
      EXPECT_NEAR(c.sim->last_report().friction_dissipated, work, 0.01 * work);
      EXPECT_GT(slid, 0.0);
    }
  }
}

TEST(Platen, TheBalanceClosesToFirstOrderInTheStep) {
  // The central difference books the springs' work as f_n (u_{n+1} - u_{n-1}) / 2, which adds
  // up to k d^2 / 2 exactly while a node touches (the sums telescope), but not over the step
  // in which it starts to touch, nor over a slip: an error of order k d (v dt) at each, so
  // that the balance of a sliding block is of first order in dt at worst: at half the step,
  // at most 0.7 of it (0.37 measured).
  std::vector<double> last;
  for (const char* safety : {"0.9", "0.45"}) {
    const fs::path dir = fresh_dir(std::string("balance_") + safety);
    std::string text = tilted(1.0e4, "1.0e-3");
    text.replace(text.find("[time]"), 6, std::string("[time]\nsafety = ") + safety);
    std::ofstream(dir / "case.toml") << text;
    RunOptions o;
    o.plots = false;
    o.out_dir = (dir / "out").string();
    ASSERT_EQ(run_command((dir / "case.toml").string(), o), 0);
    const auto e = testing::csv_columns(dir / "out" / "energy.csv");
    // external work = elastic + kinetic + contact + friction; friction about 1.7 J by the end.
    EXPECT_GT(e.at("friction_dissipated").back(), 1.0);
    last.push_back(e.at("balance_error").back());
    fs::remove_all(dir);
  }
  EXPECT_LT(last[0], 1e-3);
  EXPECT_LT(last[1], 0.7 * last[0]);
}

TEST(Platen, AFallingBlockDoesNotPassThePlatenAndBouncesBack) {
  // The block starts 1 mm above the floor and falls at g = 1e4 m/s^2: it hits at
  // v = sqrt(2 g h) = 4.5 m/s. Its base stops within v sqrt(m / sum k) = 4.5 * sqrt(0.1536 /
  // 4.8e9) = 25 um (all of its kinetic energy in the base's springs), less as the block takes
  // some of it; no node may go further.
  BuiltCase c = built(block(4, 4, 4, std::string(kGravity) + R"(
[[platen]]
name = "floor"
point = [0.0, 0.0, -0.001]
normal = [0.0, 0.0, 1.0]
[time]
end = 1.2e-3
)"),
                      "fall");
  const auto steps = run_steps(c.spec.end_time, c.sim->dt());
  const double v = std::sqrt(2.0 * 1.0e4 * 1.0e-3);
  const double reach = v * std::sqrt(kRho * std::pow(4 * kL, 3) / (kE * 16 * kL));
  double lowest = 0.0, top_speed = 0.0;
  bool touched = false;
  for (std::uint64_t n = 0; n < steps; ++n) {
    c.sim->step();
    touched = touched || c.sim->platen_contacts(0) > 0;
    for (index_t q = 0; q < c.sim->lattice().num_nodes(); ++q)
      lowest = std::min(lowest, c.sim->lattice().position(q).z + c.sim->displacement(q).z);
    if (touched && c.sim->platen_contacts(0) == 0) { // in the air again: moving up
      double m = 0.0, p = 0.0;
      for (index_t q = 0; q < c.sim->lattice().num_nodes(); ++q) {
        m += c.sim->mass(q);
        p += c.sim->mass(q) * c.sim->half_step_velocity(q).z;
      }
      top_speed = std::max(top_speed, p / m);
    }
  }
  EXPECT_TRUE(touched);
  EXPECT_GT(lowest, -0.001 - reach);
  EXPECT_LT(lowest, -0.001); // it did touch and press
  // It bounced: the springs are elastic (part of the energy stays in the block's ringing).
  EXPECT_GT(top_speed, 0.3 * v);
}

TEST(Platen, AResumedRunWritesTheBytesOfAWholeOne) {
  // The friction's sticking springs and the platen's place are in the checkpoint.
  const fs::path dir = fresh_dir("resume");
  std::ofstream(dir / "whole.toml") << tilted(1.0e4, "1.0e-3");
  std::ofstream(dir / "half.toml") << tilted(1.0e4, "5.0e-4");
  RunOptions o;
  o.plots = false;
  o.out_dir = (dir / "whole").string();
  ASSERT_EQ(run_command((dir / "whole.toml").string(), o), 0);
  o.out_dir = (dir / "half").string();
  ASSERT_EQ(run_command((dir / "half.toml").string(), o), 0);
  ASSERT_EQ(resume_command(o.out_dir, 0, false, 0, 0, 1.0e-3), 0);
  const auto text = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  for (const char* f : {"probes.csv", "energy.csv"})
    EXPECT_EQ(text(dir / "half" / f), text(dir / "whole" / f)) << f;
  EXPECT_NE(text(dir / "whole" / "energy.csv").find("friction_dissipated"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Platen, BadPlatensAreRefused) {
  const std::string good = tilted(1.0e4, "1.0e-3");
  const auto error_of = [](const std::string& text) -> std::string {
    try {
      parse_case(text, "block.toml");
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  ASSERT_EQ(error_of(good), "");
  const auto edit = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  const std::pair<std::string, std::string> cases[] = {
      {edit("normal = [0.0, 0.0, 1.0]\n", ""), "platen[0].normal: missing"},
      {edit("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]"),
       "platen[0].normal: expected a vector that is not zero"},
      {edit("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 1.0]\nradius = 0.01"),
       "platen[0].radius: does not apply to a \"plane\" platen"},
      {edit("normal = [0.0, 0.0, 1.0]", "shape = \"cylinder\"\naxis = [0.0, 1.0, 0.0]"),
       "platen[0].radius: missing"},
      {edit("normal = [0.0, 0.0, 1.0]", "shape = \"cylinder\"\nnormal = [1.0, 0.0, 0.0]"),
       "platen[0].normal: does not apply to a \"cylinder\" platen"},
      {edit("friction = 0.5", "friction = -0.5"), "platen[0].friction"},
      {edit("friction = 0.5", "penalty = 0.0"), "platen[0].penalty"},
      {edit("point = [0.0, 0.0, 0.0]\n", ""), "platen[0].point: missing"},
      {edit("platen = \"floor\"", "platen = \"flor\""),
       "probe[0].platen: expected the name of a [[platen]], got \"flor\""},
      {edit("name = \"floor\"", "name = \"floor\"\nvelocity = [0.0, 0.0, 0.1]\nramp = 1.0e-4\n"
                                "function = [{ type = \"constant\" }]"),
       "platen[0].ramp: expected ramp or function, not both"},
      {edit("[[platen]]", "[[platen]]\nname = \"floor\"\npoint = [0.0, 0.0, 1.0]\nnormal = [0.0, "
                          "0.0, -1.0]\n[[platen]]"),
       "platen[1].name: expected a name no other platen has"},
  };
  for (const auto& [text, want] : cases) {
    if (want.empty())
      continue;
    const std::string got = error_of(text);
    EXPECT_NE(got.find(want), std::string::npos) << "want: " << want << "\ngot: " << got;
    EXPECT_NE(got.find("block.toml:"), std::string::npos) << got;
  }
}

} // namespace
} // namespace ldem
