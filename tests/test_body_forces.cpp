// Body forces (an acceleration on every node's lumped mass) and forces spread over a surface by
// the area each node stands for (traction and total on any set that covers some surface).
#include "app/case_run.hpp"
#include "csv_columns.hpp"
#include "lattice/node_set.hpp"
#include "util/error.hpp"

#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <gtest/gtest.h>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace fs = std::filesystem;

namespace ldem {
namespace {

// A fresh folder for the running test.
fs::path test_dir() {
  const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::path(::testing::TempDir()) / fmt::format("ldem_{}_{}", test->name(), ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

BuiltCase built(const std::string& text) {
  const std::string path = (test_dir() / "case.toml").string();
  std::ofstream(path) << text;
  return build_case(path);
}

std::string build_error_of(const std::string& text) {
  try {
    built(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// On a box, the surface a face set covers is that face: the areas are face_tributary_areas'
// (L^2 / 4 at the face's corners, L^2 / 2 on its border, L^2 inside).
TEST(SurfaceAreas, OnABoxFaceTheyAreTheFaceTributaryAreas) {
  const Lattice lat(3, 2, 4, 0.5);
  for (int f = 0; f < 6; ++f) {
    const auto face = static_cast<Face>(f);
    const std::vector<double> want = face_tributary_areas(lat, face);
    const std::vector<double> got = surface_tributary_areas(lat, select_face(lat, face));
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t q = 0; q < got.size(); ++q)
      EXPECT_DOUBLE_EQ(got[q], want[q]) << "face " << face_name(face) << ", node " << q;
  }
}

// A plate of 6 x 6 x 2 modules with a square hole of 2 x 2 modules through it. Its surface,
// counted by hand in module faces: the outer box's 2 (36 + 12 + 12) = 120, less the hole's 4
// faces on each of the two large faces, plus the hole's 4 walls of 2 x 2: 120 - 8 + 16 = 128
// L^2. Every node of the body covers it all; the set of the nodes on the hole's walls covers
// the walls alone, 16 L^2; a single node covers nothing.
TEST(SurfaceAreas, APlateWithAHoleHasItsStaircaseArea) {
  Lattice lat(6, 6, 2, 1.0);
  auto present = std::make_shared<std::vector<std::uint8_t>>(72, 1);
  for (index_t k = 0; k < 2; ++k)
    for (index_t j = 2; j < 4; ++j)
      for (index_t i = 2; i < 4; ++i)
        (*present)[i + 6 * (j + 6 * k)] = 0;
  lat.set_modules(present);
  const auto sum = [](const std::vector<double>& a) {
    return std::accumulate(a.begin(), a.end(), 0.0);
  };
  EXPECT_DOUBLE_EQ(sum(surface_tributary_areas(lat, select_all(lat))), 128.0);
  std::vector<index_t> walls;
  for (index_t k = 0; k <= 2; ++k)
    for (index_t j = 2; j <= 4; ++j)
      for (index_t i = 2; i <= 4; ++i)
        if (i == 2 || i == 4 || j == 2 || j == 4)
          walls.push_back(lat.corner(i, j, k));
  std::sort(walls.begin(), walls.end());
  const std::vector<double> wall_areas = surface_tributary_areas(lat, walls);
  EXPECT_DOUBLE_EQ(sum(wall_areas), 16.0);
  // A corner of the hole's wall at mid-thickness: a quarter of each of the two wall faces
  // above it and the two below it.
  const auto at = std::lower_bound(walls.begin(), walls.end(), lat.corner(2, 2, 1));
  EXPECT_DOUBLE_EQ(wall_areas[static_cast<std::size_t>(at - walls.begin())], 1.0);
  EXPECT_EQ(sum(surface_tributary_areas(lat, {lat.corner(0, 0, 0)})), 0.0);
}

const std::string kBlock = R"(
[lattice]
modules = [4, 4, 6]
L = 0.01

[material]
E = 30e9
rho = 2400
Gf = 100
e_p = 1e-4

[[node_set]]
name = "top"
face = "z+"

[[node_set]]
name = "all"
all = true

[[node_set]]
name = "one"
box_min = [0.0, 0.0, 0.06]
box_max = [0.0, 0.0, 0.06]

[[node_set]]
name = "mantle"
shape = { type = "cylinder", start = [0.02, 0.02, -0.01], end = [0.02, 0.02, 0.07], radius = 0.025 }
surface = true

[[fixed]]
set = "one"
dofs = "xyz"

[time]
end = 1e-5
)";

std::string with_load(const std::string& load) {
  return kBlock + "\n[[load]]\nname = \"p\"\n" + load + "\n";
}

// The forces a simulation puts on its nodes at t = 0 ([[load]] p), summed.
Vec3 total_load(const BuiltCase& c) {
  Vec3 sum;
  const NodalLoad& l = c.sim->conditions().loads.at(0);
  for (std::size_t q = 0; q < l.set.nodes.size(); ++q) {
    sum.x += l.force.x * l.weight_of(q);
    sum.y += l.force.y * l.weight_of(q);
    sum.z += l.force.z * l.weight_of(q);
  }
  return sum;
}

// total spreads its force as a traction of total / area would: the same share on each node,
// and the shares add up to the total; on the top face (area 4 x 4 L^2 = 1.6e-3 m^2) and on the
// body's surface inside a cylinder of radius 2.5 L about the block's vertical axis. That one
// leaves out the nodes on the box's vertical edges (2.83 L from the axis) and keeps the rest of
// the corner nodes of the sides and of the end faces: the module faces with four corners in it
// are, on each side, the 2 middle ones of each of the 6 layers (48 in all), and on each end face
// the 4 inner ones and the 2 middle ones along each edge (12 each): 72 L^2.
TEST(Loads, TotalIsSpreadByAreaAsATraction) {
  for (const char* set : {"top", "mantle"}) {
    const BuiltCase total = built(with_load(fmt::format("set = \"{}\"\ntotal = [0, 0, -800]", set)));
    const double area = std::accumulate(total.sim->conditions().loads[0].weight.begin(),
                                        total.sim->conditions().loads[0].weight.end(), 0.0);
    EXPECT_DOUBLE_EQ(area, std::string(set) == "top" ? 16e-4 : 72e-4) << set;
    const BuiltCase traction = built(
        with_load(fmt::format("set = \"{}\"\ntraction = [0, 0, {:.17g}]", set, -800.0 / area)));
    const NodalLoad& a = total.sim->conditions().loads[0];
    const NodalLoad& b = traction.sim->conditions().loads[0];
    ASSERT_EQ(a.set.nodes, b.set.nodes);
    for (std::size_t q = 0; q < a.set.nodes.size(); ++q)
      EXPECT_DOUBLE_EQ(a.force.z * a.weight_of(q), b.force.z * b.weight_of(q)) << set << q;
    EXPECT_NEAR(total_load(total).z, -800.0, 1e-12 * 800.0) << set;
    EXPECT_EQ(total_load(total).x, 0.0);
    // The load probe's total, and the area in the resolved case.
    EXPECT_NEAR(load_total_force(total, 0, 0.0), 800.0, 1e-12 * 800.0) << set;
  }
}

// A body force weighs each node by the simulation's own lumped mass, with a density field as
// without: the forces add up to rho V a.
TEST(Loads, AccelerationWeighsEachNodeByItsLumpedMass) {
  // The density as the case gives it, and its mean over the body: 2400 kg/m^3, or a linear
  // field from 1200 to 2400, whose modules take it at their centres (linear: the mean, 1800,
  // is exact).
  const std::pair<const char*, double> densities[] = {
      {"rho = 2400", 2400.0},
      {"rho = { type = \"linear\", axis = \"z\", values = [1200.0, 2400.0] }", 1800.0}};
  for (const auto& [rho, rho_mean] : densities) {
    std::string text = with_load("set = \"all\"\nacceleration = [0, 0, -9.81]");
    text.replace(text.find("rho = 2400"), 10, rho);
    const BuiltCase c = built(text);
    const NodalLoad& l = c.sim->conditions().loads.at(0);
    ASSERT_EQ(l.weight.size(), l.set.nodes.size());
    double mass = 0.0;
    for (std::size_t q = 0; q < l.set.nodes.size(); ++q) {
      EXPECT_EQ(l.weight[q], c.sim->mass(l.set.nodes[q])) << rho << ", node " << q;
      mass += c.sim->mass(l.set.nodes[q]);
    }
    // rho V over the block of 0.04 x 0.04 x 0.06 m.
    const double V = 0.04 * 0.04 * 0.06;
    EXPECT_NEAR(mass, rho_mean * V, 1e-12 * rho_mean * V) << rho;
    EXPECT_NEAR(total_load(c).z, -9.81 * rho_mean * V, 1e-12 * 9.81 * rho_mean * V) << rho;
    EXPECT_NEAR(load_total_force(c, 0, 0.0), 9.81 * rho_mean * V, 1e-12 * 9.81 * rho_mean * V);
  }
}

TEST(Loads, BadSpreadsAreRefused) {
  // One way to give the force.
  std::string e = build_error_of(with_load("set = \"top\"\nforce = [0, 0, 1]\ntotal = [0, 0, 1]"));
  EXPECT_NE(e.find("load[0].total: expected one of force, traction, total and acceleration, "
                   "got force and total"),
            std::string::npos)
      << e;
  e = build_error_of(with_load("set = \"top\""));
  EXPECT_NE(e.find("load[0].force: expected force (N on each node), traction"), std::string::npos)
      << e;
  // A set that covers no face of the surface has no area to spread a total over.
  e = build_error_of(with_load("set = \"one\"\ntotal = [0, 0, 1]"));
  EXPECT_NE(e.find("load \"p\" has a total: expected a node set that covers some of the body's "
                   "surface"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("case.toml:"), std::string::npos) << e; // located
}

// A column of 8 x 8 x 24 modules of 10 mm (H = 0.24 m) on rollers (its base held in z), in a
// centrifuge at a = 1000 g = 9810 m/s^2 along -z, reached over a ramp of T = 1 ms, to 2 ms. Its
// weight W = rho a V = 36.2 kN. Damping a_d = 46000 / s is twice the fundamental's angular
// frequency, (pi / 2) c / H = 23100 rad/s (c = sqrt(E / rho) = 3540 m/s): critical for it, and
// every higher mode decays at a_d / 2 at least; 1 ms after the ramp what is left of the lag
// (8.6 % of the static response at the ramp's end, 2 / (omega T)) is below 1e-8 of it. The
// column is then at rest under its weight: the stress at height z is rho a (H - z) (uniaxial;
// 5.6 MPa at the base, strain 1.9e-4, elastic: e_p = 1e-3).
constexpr double kRho = 2400.0, kA = 9810.0, kE = 30.0e9, kH = 0.24, kW = 0.08;

const char* kColumn = R"(
[lattice]
modules = [8, 8, 24]
L = 0.01

[material]
E = 30.0e9
rho = 2400.0
Gf = 1000.0
e_p = 1.0e-3

[[node_set]]
name = "bottom"
face = "z-"

[[node_set]]
name = "top"
face = "z+"

[[node_set]]
name = "body"
all = true

[[fixed]]
set = "bottom"
dofs = "z"

[time]
end = 2.0e-3
damping = 46000.0

[output]
energy_every = 100
vtu = false
plots = false

[[probe]]
name = "load"
kind = "load"
load = "p"

[[probe]]
name = "base"
kind = "reaction"
set = "bottom"
component = "z"

[[probe]]
name = "middle"
kind = "strain"
from = [0.04, 0.04, 0.08]
to = [0.04, 0.04, 0.16]
)";

// The column's run with the load `load` ([[load]] p, ramped over 1 ms): its last row of
// probes.csv and of energy.csv.
std::map<std::string, double> loaded_column(const std::string& load, const std::string& name) {
  const fs::path dir = test_dir() / name;
  fs::create_directories(dir);
  std::ofstream(dir / "column.toml")
      << kColumn << "\n[[load]]\nname = \"p\"\n"
      << load << "\nfunction = [{ type = \"ramp\", duration = 1.0e-3 }]\n";
  RunOptions o;
  o.out_dir = (dir / "out").string();
  o.plots = false;
  EXPECT_EQ(run_command((dir / "column.toml").string(), o), 0);
  std::map<std::string, double> last;
  for (const char* file : {"probes.csv", "energy.csv"})
    for (const auto& [column, values] : testing::csv_columns(dir / "out" / file))
      last[column] = values.empty() ? NAN : values.back();
  return last;
}

TEST(Loads, ColumnUnderItsWeightCarriesItToTheBase) {
  const double W = kRho * kA * kW * kW * kH;
  const auto weight = loaded_column("set = \"body\"\nacceleration = [0.0, 0.0, -9810.0]", "weight");
  // The same column pressed by its weight on its top face (total spread by area).
  const auto pressed =
      loaded_column(fmt::format("set = \"top\"\ntotal = [0.0, 0.0, {:.17g}]", -W), "pressed");
  // probes.csv holds 9 significant digits: values compared through it agree to 1e-8.
  constexpr double kCsv = 1e-8;
  // The load probes: the acceleration times the lumped masses, which add up to rho V; the
  // total as given.
  EXPECT_NEAR(weight.at("load"), W, kCsv * W);
  EXPECT_NEAR(pressed.at("load"), W, kCsv * W);
  // At rest, the rollers carry the whole weight.
  EXPECT_NEAR(weight.at("base"), W, 3 * kCsv * W);
  EXPECT_NEAR(pressed.at("base"), W, 3 * kCsv * W);
  // Pressed, the section carries W at every height; under its weight, W (H - z) / H, which
  // over the middle gauge (z from 0.08 to 0.16 m, mid-height H / 2) averages W / 2: the gauge
  // reads half the strain. Both gauges lie a section's width (8 modules) from the ends, where
  // the disturbances of the supports and of the top's load (on its corner nodes only) have
  // died out (Saint-Venant): measured 2e-4 apart; within 2e-3. The section's stiffness, the
  // same in both, drops out.
  EXPECT_NEAR(weight.at("middle"), 0.5 * pressed.at("middle"),
              2e-3 * 0.5 * std::abs(pressed.at("middle")));
  // That stiffness: an 8 x 8 section is softer than E A by 1.0 % (its free faces' first layer
  // of modules does not follow the uniaxial field: docs/model.md): within 2 %.
  const double strain = W / (kW * kW * kE);
  EXPECT_NEAR(pressed.at("middle"), -strain, 0.02 * strain);
  // The energy balance closes: the body force's work is in external_work.
  for (const auto* run : {&weight, &pressed}) {
    EXPECT_GT(run->at("external_work"), 0.0);
    EXPECT_LT(std::abs(run->at("balance_error")), 1e-6 * run->at("external_work"));
  }
}

} // namespace
} // namespace ldem
