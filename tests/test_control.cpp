// Loading controlled by a gauge probe ([[velocity]] control): the controller's law on a gauge
// that moves as the driven set does, where its recurrence has a closed form, and a notched
// beam followed through its softening at a constant crack mouth opening rate (CMOD control).
#include "app/case_run.hpp"
#include "csv_columns.hpp"
#include "util/error.hpp"

#include <algorithm>
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

// A column of 4 x 4 x 12 modules of 10 mm on rollers (its base held in z), its top face driven
// along z by a controller that makes the top's LVDT follow rate * t. The step is given, so that
// t_n = n dt is known exactly.
constexpr double kDt = 1.0e-6, kT = 2.0e-4;

std::string column(double top_speed, double rate) {
  std::ostringstream s;
  s.precision(17);
  s << R"(
[lattice]
modules = [4, 4, 12]
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
value = [0.0, 0.0, )"
    << top_speed << R"(]
control = { probe = "lvdt", rate = )"
    << rate << ", response_time = " << kT << R"( }

[time]
end = 2.0e-3
rule = "dt"
dt = )" << kDt
    << R"(

[output]
energy_every = 50
vtu = false
plots = false

[[probe]]
name = "lvdt"
kind = "displacement"
set = "top"
)";
  return s.str();
}

// The run of a case text: probes.csv by column. `name` keeps the runs' folders apart.
std::map<std::string, std::vector<double>> run_text(const std::string& text,
                                                    const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("ldem_control_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "case.toml").string();
  std::ofstream(path) << text;
  RunOptions o;
  o.out_dir = (dir / "out").string();
  o.plots = false;
  EXPECT_EQ(run_command(path, o), 0);
  auto columns = testing::csv_columns(dir / "out" / "probes.csv");
  fs::remove_all(dir);
  return columns;
}

TEST(Control, AGaugeOnTheDrivenSetFollowsItsTarget) {
  // The gauge is the driven set's own displacement (G = 1): g_{n+1} = g_n + dt V f_n with
  // f_n = (rate t_{n+1} - g_n) / (T V) (docs/model.md, "Probe-controlled loading"), so the
  // error e_n = rate t_n - g_n obeys e_{n+1} = (1 - a) (e_n + rate dt), a = dt / T, e_0 = 0:
  // e_n = rate (T - dt) (1 - (1 - a)^n). f_n = (e_n + rate dt) / (T V) <= rate / V = 0.2:
  // never clamped. Either sign of the rate: the set is drawn back along -value for a negative
  // one.
  for (const double rate : {0.01, -0.01}) {
    const auto c = run_text(column(0.05, rate), rate > 0 ? "pull" : "push");
    ASSERT_EQ(c.at("time").size(), 41u);
    for (std::size_t r = 0; r < c.at("time").size(); ++r) {
      const double n = 50.0 * static_cast<double>(r), t = n * kDt;
      const double expected = rate * t - rate * (kT - kDt) * (1.0 - std::pow(1.0 - kDt / kT, n));
      // probes.csv holds 9 significant digits.
      EXPECT_NEAR(c.at("lvdt")[r], expected, 1e-8 * std::abs(expected) + 1e-15)
          << "rate " << rate << ", t = " << t;
    }
  }
  // A top speed below the rate: once the error passes T V - rate dt (about 1e-6 m, reached
  // from the closed form above near step 137), f is clamped at 1 and the set moves at V, the
  // error growing ever after (the target runs at rate > V): from the 4th row on (step 150),
  // the gauge gains V times the time between rows exactly.
  const double v = 0.005;
  const auto c = run_text(column(v, 0.01), "clamped");
  for (std::size_t r = 4; r < c.at("time").size(); ++r) {
    const double gain = c.at("lvdt")[r] - c.at("lvdt")[r - 1];
    EXPECT_NEAR(gain, v * 50.0 * kDt, 1e-8 * c.at("lvdt")[r]) << "row " << r;
  }
  // Before it, the unclamped recurrence: at row 2 (step 100) the closed form.
  const double n = 100.0;
  EXPECT_NEAR(c.at("lvdt")[2],
              0.01 * n * kDt - 0.01 * (kT - kDt) * (1.0 - std::pow(1.0 - kDt / kT, n)), 1e-15);
}

// The notched beam of cases/specimens/notched_beam.toml at L = 5 mm (88 x 1 x 20 modules, a
// notch two modules wide to half the depth, 5 mm thick), its load line driven down by a
// controller that opens the crack mouth at 7.5 mm/s: 0.3 mm by the end, far down the tail.
const char* kBeam = R"(
[lattice]
modules = [88, 1, 20]
L = 0.005
plane_strain = "y"

[material]
E = 30.0e9
rho = 2400.0
Gf = 100.0
e_p = 1.0e-4

[[geometry]]
remove = { type = "box", min = [0.214, -1.0, -1.0], max = [0.226, 1.0, 0.05] }

[[node_set]]
name = "pin"
box_min = [0.02, -1.0, 0.0]
box_max = [0.02, 1.0, 0.0]

[[node_set]]
name = "roller"
box_min = [0.42, -1.0, 0.0]
box_max = [0.42, 1.0, 0.0]

[[node_set]]
name = "load_line"
box_min = [0.215, -1.0, 0.1]
box_max = [0.225, 1.0, 0.1]

[[fixed]]
set = "pin"
dofs = "xz"

[[fixed]]
set = "roller"
dofs = "z"

[[velocity]]
set = "load_line"
dofs = "z"
value = [0.0, 0.0, -0.05]
control = { probe = "cmod", rate = 7.5e-3 }

[time]
end = END
damping = 2000.0

[output]
energy_every = 500
vtu = false
plots = false

[[probe]]
name = "load"
kind = "reaction"
set = "load_line"
component = "z"

[[probe]]
name = "cmod"
kind = "opening"
from = [0.215, 0.0, 0.0]
to = [0.225, 0.0, 0.0]
component = "x"

[[probe]]
name = "deflection"
kind = "displacement"
set = "load_line"
component = "z"
)";

std::string beam(const std::string& end) {
  std::string s = kBeam;
  s.replace(s.find("END"), 3, end);
  return s;
}

std::string file_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Control, ANotchedBeamUnderCmodControlSoftensAtAConstantOpeningRate) {
  const fs::path dir = fs::temp_directory_path() / "ldem_control_beam";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "whole.toml") << beam("0.04");
  std::ofstream(dir / "half.toml") << beam("0.02");
  RunOptions o;
  o.plots = false;
  o.out_dir = (dir / "whole").string();
  ASSERT_EQ(run_command((dir / "whole.toml").string(), o), 0);
  auto c = testing::csv_columns(dir / "whole" / "probes.csv");
  const auto energy = testing::csv_columns(dir / "whole" / "energy.csv");

  // The default response time: 20 crossings of the beam's length by a bar wave.
  const double rate = 7.5e-3, T = 20.0 * 0.44 / std::sqrt(30.0e9 / 2400.0);
  const std::vector<double>&t = c.at("time"), &cmod = c.at("cmod"), &load = c.at("load");
  ASSERT_GT(t.size(), 50u);
  double peak = 0.0;
  for (std::size_t r = 0; r < t.size(); ++r) {
    peak = std::max(peak, -load[r]); // the load line is pushed down: its reaction is negative
    // The mouth never closes: the controller draws the load line back only to slow it.
    if (r > 0) {
      EXPECT_GE(cmod[r], cmod[r - 1] - 1e-8 * cmod[r]) << "t = " << t[r];
    }
    // Once the start has settled (3 T), the CMOD lags its target by rate T / G, G the CMOD per
    // load-line deflection: 4 D / S = 1 for the halves turning as rigid bodies about the crack
    // tip, less while the beam bends elastically (about 0.7 here before the peak). G in
    // [0.6, 1.5] puts the lag in [rate T / 1.5, rate T / 0.6]: the CMOD runs at `rate` on
    // average, whatever the load does.
    if (t[r] > 3.0 * T) {
      const double lag = rate * t[r] - cmod[r];
      EXPECT_GT(lag, rate * T / 1.5) << "t = " << t[r];
      EXPECT_LT(lag, rate * T / 0.6) << "t = " << t[r];
    }
  }
  // The load rises to a peak and the controller follows the softening branch down to below a
  // quarter of it (0.3 mm of opening), with the energy balance closed.
  EXPECT_GT(peak, 50.0);
  EXPECT_LT(-load.back(), 0.25 * peak);
  for (double e : energy.at("balance_error"))
    EXPECT_LT(std::abs(e), 1e-5);

  // The controller keeps no state of its own: the run to 0.02 s resumed to 0.04 s writes the
  // same logs as the run to 0.04 s, byte for byte (with the same steps between rows).
  o.out_dir = (dir / "half").string();
  ASSERT_EQ(run_command((dir / "half.toml").string(), o), 0);
  ASSERT_EQ(resume_command(o.out_dir, 0, false, 0, 0, 0.04), 0);
  for (const char* f : {"probes.csv", "energy.csv", "events.csv"})
    EXPECT_EQ(file_text(dir / "half" / f), file_text(dir / "whole" / f)) << f;
  fs::remove_all(dir);
}

TEST(Control, BadControlsAreRefused) {
  const auto error_of = [](const std::string& text) -> std::string {
    try {
      parse_case(text, "beam.toml");
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  const std::string good = beam("0.04");
  ASSERT_EQ(error_of(good), "");
  const auto edit = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  const std::string line = "control = { probe = \"cmod\", rate = 7.5e-3 }";
  EXPECT_NE(error_of(edit(line, "control = { probe = \"load\", rate = 7.5e-3 }"))
                .find("beam.toml:43: velocity[0].control.probe: expected a displacement, opening "
                      "or strain probe (a gauge), got \"load\""),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, "control = { probe = \"cmd\", rate = 7.5e-3 }"))
                .find("velocity[0].control.probe: expected the name of a [[probe]], got \"cmd\""),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, "control = { probe = \"cmod\", rate = 0.0 }"))
                .find("velocity[0].control.rate: expected a rate that is not 0"),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, "control = { probe = \"cmod\" }"))
                .find("velocity[0].control.rate: missing required key"),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, line + "\nramp = 1.0e-3"))
                .find("velocity[0].ramp: does not apply to a controlled velocity"),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, "control = { probe = \"cmod\", rate = 7.5e-3, gain = 2 }"))
                .find("velocity[0].control.gain: unknown key"),
            std::string::npos);
  EXPECT_NE(error_of(edit(line, "control = 3.0")).find("velocity[0].control: expected a table"),
            std::string::npos);
  EXPECT_NE(error_of(edit("value = [0.0, 0.0, -0.05]", "value = [0.0, 0.0, 0.0]"))
                .find("velocity[0].value: expected a velocity that is not zero"),
            std::string::npos);
  EXPECT_NE(
      error_of(edit(line, "control = { probe = \"cmod\", rate = 7.5e-3, response_time = 0 }"))
          .find("velocity[0].control.response_time"),
      std::string::npos);
}

} // namespace
} // namespace ldem
