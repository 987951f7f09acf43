// The gauges a laboratory puts on a specimen (displacement, opening and strain probes), on an
// elastic column pulled slowly: what each records follows from the imposed motion and from
// uniaxial elasticity.
#include "app/case_run.hpp"
#include "csv_columns.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace ldem {
namespace {

// A column of 8 x 8 x 24 modules of 10 mm (H = 0.24 m), resting on rollers (its base held in z
// only), its top driven up at v = 0.01 m/s reached over a ramp of T = 1 ms, to 2 ms. The wave
// crosses it in H / sqrt(E / rho) = 68 us, far shorter than the ramp, and the damping takes the
// ringing out: the pull is quasi-static and the column in uniaxial tension, strain 6e-5 at the
// end (elastic: e_p = 1e-3). The centre nodes of the end layers are driven on the affine field
// (v / 48 and 47 v / 48: docs/model.md, "The first layer along a face"), so that the strain is
// the same in every layer.
constexpr double kV = 0.01, kRamp = 1.0e-3, kH = 0.24, kW = 0.06;

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

[[fixed]]
set = "bottom"
dofs = "z"

[[velocity]]
set = "top"
dofs = "z"
value = [0.0, 0.0, 0.01]
ramp = 1.0e-3

[[node_set]]
name = "bottom_centres"
face_centres = "z-"

[[node_set]]
name = "top_centres"
face_centres = "z+"

[[velocity]]
set = "bottom_centres"
dofs = "z"
value = [0.0, 0.0, 0.000208333333333333333]
ramp = 1.0e-3

[[velocity]]
set = "top_centres"
dofs = "z"
value = [0.0, 0.0, 0.00979166666666666667]
ramp = 1.0e-3

[time]
end = 2.0e-3
damping = 3000.0

[output]
energy_every = 50
vtu = false
plots = false

[[probe]]
name = "lvdt_top"
kind = "displacement"
set = "top"

[[probe]]
name = "corner"
kind = "displacement"
at = [0.0801, 0.0801, 0.25]

[[probe]]
name = "opening"
kind = "opening"
from_set = "bottom"
to_set = "top"

[[probe]]
name = "strain_whole"
kind = "strain"
from_set = "bottom"
to_set = "top"

[[probe]]
name = "strain_mid"
kind = "strain"
from = [0.04, 0.04, 0.06]
to = [0.04, 0.04, 0.18]

[[probe]]
name = "width"
kind = "opening"
from = [0.01, 0.04, 0.12]
to = [0.07, 0.04, 0.12]
component = "x"
)";

// probes.csv of the column's run, by column name.
std::map<std::string, std::vector<double>> run_column() {
  const fs::path dir = fs::temp_directory_path() / "ldem_probes_column";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "column.toml").string();
  std::ofstream(path) << kColumn;
  RunOptions o;
  o.out_dir = (dir / "out").string();
  o.plots = false;
  EXPECT_EQ(run_command(path, o), 0);
  auto columns = testing::csv_columns(dir / "out" / "probes.csv");
  fs::remove_all(dir);
  return columns;
}

TEST(Probes, GaugesOnAColumnPulledSlowly) {
  const auto c = run_column();
  ASSERT_GT(c.at("time").size(), 10u);
  // probes.csv holds 9 significant digits: values compared through it agree to 1e-8.
  constexpr double kCsv = 1e-8;
  for (std::size_t r = 0; r < c.at("time").size(); ++r) {
    const double t = c.at("time")[r], top = c.at("lvdt_top")[r];
    // The top nodes move as imposed: u = v t^2 / (2 T) on the ramp, v (t - T / 2) after it.
    // The step integrates the velocity at mid-steps, which is exact for the linear ramp and
    // the constant; only the step across t = T is off, by at most v dt^2 / (8 T), 5e-12 m
    // for dt <= 2 us (here dt = 1.6 us).
    const double expected = t < kRamp ? kV * t * t / (2.0 * kRamp) : kV * (t - 0.5 * kRamp);
    EXPECT_NEAR(top, expected, kCsv * std::abs(expected) + 5e-12) << "t = " << t;
    // The node nearest a point above the top's corner is that corner, one of the nodes whose
    // mean the set probe takes: all move alike, so the mean is the node's value (to rounding).
    EXPECT_NEAR(c.at("corner")[r], top, kCsv * std::abs(top)) << "t = " << t;
    // The base is held in z: the opening between base and top is the top's displacement
    // (exactly: the base's terms are zeros), and their strain that over the height (the
    // gauge's direction is z exactly: both faces' centroids have the same x and y).
    EXPECT_EQ(c.at("opening")[r], top) << "t = " << t;
    EXPECT_NEAR(c.at("strain_whole")[r], top / kH, kCsv * std::abs(top / kH)) << "t = " << t;
  }
  // At the end, quasi-static uniaxial tension with every layer on the affine field: an
  // extensometer over the middle half reads the column's mean strain. What is left of the
  // dynamic response: the fundamental mode (period 4 H / c = 0.27 ms), excited at the ramp's
  // end with an amplitude of about (v / c) / (omega T) ~ 1e-4 of the strain and damped by
  // exp(-damping t / 2) since: below 1e-3 of the strain.
  const double e = c.at("strain_whole").back();
  EXPECT_NEAR(c.at("strain_mid").back(), e, 1e-3 * e);
  // The width contracts by nu = 0.25 (the lattice's Poisson ratio, docs/model.md) times it,
  // measured between the nodes one module inside the free faces x = 0 and x = 8 L. The first
  // layer along those faces does not follow the affine field (its centre nodes are pulled
  // inwards by 0.1 E L^2 eps, docs/model.md) and disturbs the interior by less than its own
  // share of the section (1 layer in 8 on each side); measured 0.15 % here, 0.4 % on a
  // section of 4 modules: within 0.5 %.
  EXPECT_NEAR(c.at("width").back(), -0.25 * e * kW, 0.005 * 0.25 * e * kW);
}

} // namespace
} // namespace ldem
