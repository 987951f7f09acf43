// Case files: every kind of bad input gets a located, specific message.
#include "io/case_spec.hpp"
#include "util/error.hpp"

#include <gtest/gtest.h>
#include <string>

namespace ldem {
namespace {

const std::string kGood = R"(
[lattice]
modules = [4, 1, 4]
L = 0.01
plane_strain = "y"

[material]
E = 30e9
rho = 2400
Gf = 100
e_p = 1e-4

[[node_set]]
name = "top"
face = "z+"

[[velocity]]
set = "top"
dofs = "z"
value = [0, 0, 0.01]
function = [{ type = "ramp", duration = 1e-4 }, { type = "constant", value = 0.5 }]

[time]
end = 1e-4
)";

// Replaces the first occurrence of `from` in the good case.
std::string edit(const std::string& from, const std::string& to) {
  std::string s = kGood;
  const auto p = s.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  return s.replace(p, from.size(), to);
}

std::string error_of(const std::string& text) {
  try {
    parse_case(text, "case.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(CaseFile, GoodCaseParsesWithDefaults) {
  const CaseSpec c = parse_case(kGood, "case.toml");
  EXPECT_EQ(c.nx, 4u);
  EXPECT_EQ(c.nz, 4u);
  EXPECT_EQ(c.plane_strain_axis, 1);
  EXPECT_DOUBLE_EQ(c.material.nu, 0.25); // declared default
  EXPECT_DOUBLE_EQ(c.step.safety, 0.9);  // declared default
  EXPECT_EQ(c.step.rule, TimeStep::Rule::Safety);
  ASSERT_EQ(c.velocities.size(), 1u);
  EXPECT_EQ(c.velocities[0].dofs, kDofZ);
  // ramp(t = duration / 2) = 0.5, plus the constant 0.5.
  EXPECT_DOUBLE_EQ(c.velocities[0].scale(0.5e-4), 1.0);
}

// A key the reader knows but that does not apply to what its table is (t_start on a ramp, an
// axis on a random field, a covariance without a correlation length, a courant number without
// the paper's rule, a point on a reaction probe) is refused like an unknown key, not dropped.
// law = "bilinear_fatigue" needs a [fatigue] table, which applies to it alone; its values are
// read with their defaults (threshold 0, the gate 0 meaning 1 % of e_p, count_every 10, A
// given for bars of length L) and their ranges.
TEST(CaseFile, FatigueLawAndItsTable) {
  const std::string with_law = edit("e_p = 1e-4", "e_p = 1e-4\nlaw = \"bilinear_fatigue\"");
  std::string e = error_of(with_law);
  EXPECT_NE(e.find("case.toml:12: material.law: law = \"bilinear_fatigue\" needs a [fatigue] "
                   "table"),
            std::string::npos)
      << e;
  e = error_of(kGood + "\n[fatigue]\nA = 1e10\nm = 4\n");
  EXPECT_NE(e.find("fatigue: a [fatigue] table applies to law = \"bilinear_fatigue\", not "
                   "\"bilinear\""),
            std::string::npos)
      << e;
  const CaseSpec c = parse_case(with_law + "\n[fatigue]\nA = 1e10\nm = 4\n", "case.toml");
  ASSERT_TRUE(c.material.fatigue.has_value());
  EXPECT_EQ(c.law, "bilinear_fatigue");
  EXPECT_EQ(c.material.fatigue->A, 1e10);
  EXPECT_EQ(c.material.fatigue->m, 4.0);
  EXPECT_EQ(c.material.fatigue->threshold, 0.0);
  EXPECT_EQ(c.material.fatigue->gate, 0.0);
  EXPECT_EQ(c.material.fatigue->count_every, 10u);
  EXPECT_EQ(c.material.fatigue->length, 0.01); // the case's L
  e = error_of(with_law + "\n[fatigue]\nA = -1\nm = 4\n");
  EXPECT_NE(e.find("fatigue.A: expected a value > 0"), std::string::npos) << e;
  e = error_of(with_law + "\n[fatigue]\nA = 1e10\nm = 4\ngate = nan\n");
  EXPECT_NE(e.find("fatigue.gate"), std::string::npos) << e;
  e = error_of(with_law + "\n[fatigue]\nA = 1e10\nm = 4\ncount_every = 0\n");
  EXPECT_NE(e.find("fatigue.count_every: expected a value [1, 1e+06]"), std::string::npos) << e;
  e = error_of(with_law + "\n[fatigue]\nA = 1e10\nm = 4\nphase = 2\n");
  EXPECT_NE(e.find("fatigue.phase: unknown key"), std::string::npos) << e;
  // The box of the bars with a fatigue life: both corners, the second at or above the first.
  EXPECT_FALSE(c.material.fatigue->box.has_value());
  e = error_of(with_law + "\n[fatigue]\nA = 1e10\nm = 4\nbox_min = [0, 0, 0.01]\n");
  EXPECT_NE(e.find("fatigue.box_max: missing: box_min needs box_max"), std::string::npos) << e;
  e = error_of(with_law + "\n[fatigue]\nA = 1e10\nm = 4\nbox_min = [0, 0, 0.02]\n"
                          "box_max = [0.04, 0.01, 0.01]\n");
  EXPECT_NE(e.find("fatigue.box_max: expected a corner at or above box_min [0, 0, 0.02] in x, y "
                   "and z, got [0.04, 0.01, 0.01]"),
            std::string::npos)
      << e;
  const CaseSpec b = parse_case(with_law + "\n[fatigue]\nA = 1e10\nm = 4\nbox_min = [0, 0, "
                                           "0.01]\nbox_max = [0.04, 0.01, 0.02]\n",
                                "case.toml");
  ASSERT_TRUE(b.material.fatigue->box.has_value());
  EXPECT_EQ((*b.material.fatigue->box)[0].z, 0.01);
  EXPECT_EQ((*b.material.fatigue->box)[1].x, 0.04);
}

TEST(CaseFile, KeysThatDoNotApplyAreRefused) {
  std::string e = error_of(edit("{ type = \"ramp\", duration = 1e-4 }",
                                "{ type = \"ramp\", duration = 1e-4, n_cycles = 2 }"));
  EXPECT_NE(e.find("case.toml:21: velocity[0].function[0].n_cycles: does not apply to a \"ramp\" "
                   "term (its keys: type, value, duration, t_start, t_end)"),
            std::string::npos)
      << e;
  e = error_of(edit("E = 30e9", "E = { type = \"weibull\", mean = 30e9, cv = 0.1, axis = \"x\" }"));
  EXPECT_NE(e.find("material.E.axis: does not apply to an uncorrelated \"weibull\" field"),
            std::string::npos)
      << e;
  e = error_of(edit("E = 30e9", "E = { type = \"weibull\", mean = 30e9, cv = 0.1, covariance = "
                                "\"exponential\" }"));
  EXPECT_NE(e.find("material.E.covariance: does not apply to an uncorrelated"), std::string::npos)
      << e;
  EXPECT_EQ(error_of(edit("E = 30e9", "E = { type = \"weibull\", mean = 30e9, cv = 0.1, "
                                      "correlation_length = 0.02, covariance = \"exponential\" }")),
            "");
  e = error_of(edit("end = 1e-4", "end = 1e-4\ncourant = 0.5"));
  EXPECT_NE(e.find("time.courant: does not apply to rule = \"safety\""), std::string::npos) << e;
  e = error_of(kGood + "\n[[probe]]\nname = \"r\"\nkind = \"reaction\"\nset = \"top\"\n"
                       "at = [0, 0, 0]\n");
  EXPECT_NE(e.find("probe[0].at: does not apply to a \"reaction\" probe (its keys: name, kind, "
                   "set, component)"),
            std::string::npos)
      << e;  // A gauge's end is a point or a node set, one of the two; a strain has no component.
  const std::string probe = kGood + "\n[[probe]]\nname = \"g\"\n";
  e = error_of(probe + "kind = \"displacement\"\nat = [0, 0, 0]\nset = \"top\"\n");
  EXPECT_NE(e.find("probe[0].set: expected either at = [x, y, z] or set = \"<node set>\" for a "
                   "\"displacement\" probe, got both"),
            std::string::npos)
      << e;
  e = error_of(probe + "kind = \"opening\"\nfrom = [0, 0, 0]\n");
  EXPECT_NE(e.find("probe[0].to: expected either to = [x, y, z] or to_set = \"<node set>\" for an "
                   "\"opening\" probe, got neither"),
            std::string::npos)
      << e;
  e = error_of(probe + "kind = \"strain\"\nfrom = [0, 0, 0]\nto_set = \"bottom\"\n");
  EXPECT_NE(e.find("probe[0].to_set: expected the name of a [[node_set]], got \"bottom\""),
            std::string::npos)
      << e;
  e = error_of(probe + "kind = \"strain\"\nfrom = [0, 0, 0]\nto = [0, 0, 1]\ncomponent = \"x\"\n");
  EXPECT_NE(e.find("probe[0].component: does not apply to a \"strain\" probe"), std::string::npos)
      << e;
}

TEST(CaseFile, MalformedToml) {
  const std::string e = error_of(edit("L = 0.01", "L = = 0.01"));
  EXPECT_NE(e.find("case.toml:4: malformed TOML"), std::string::npos) << e;
}

TEST(CaseFile, UnknownKeyWithSuggestion) {
  const std::string e = error_of(edit("Gf = 100", "Gff = 100"));
  EXPECT_NE(e.find("case.toml:10: material.Gff: unknown key in [material]; did you mean \"Gf\"?"),
            std::string::npos)
      << e;
}

TEST(CaseFile, UnknownTable) {
  const std::string e = error_of(kGood + "\n[outptu]\nvtu = false\n");
  EXPECT_NE(e.find("outptu: unknown table; did you mean \"output\"?"), std::string::npos) << e;
}

TEST(CaseFile, WrongType) {
  const std::string e = error_of(edit("E = 30e9", "E = \"stiff\""));
  EXPECT_NE(e.find("case.toml:8: material.E: expected a number (Pa), got \"stiff\""),
            std::string::npos)
      << e;
}

TEST(CaseFile, OutOfRange) {
  std::string e = error_of(edit("e_p = 1e-4", "e_p = 1e-4\nnu = 0.6"));
  EXPECT_NE(e.find("material.nu: expected a value (0, 0.5), got 0.6"), std::string::npos) << e;
  e = error_of(edit("L = 0.01", "L = -0.01"));
  EXPECT_NE(e.find("case.toml:4: lattice.L: expected a value [1e-09, 1000] (m), got -0.01"),
            std::string::npos)
      << e;
  e = error_of(edit("dofs = \"z\"", "dofs = \"w\""));
  EXPECT_NE(e.find("velocity[0].dofs: expected letters among x, y, z, got \"w\""),
            std::string::npos)
      << e;
  e = error_of(edit("plane_strain = \"y\"", "plane_strain = \"q\""));
  EXPECT_NE(
      e.find("lattice.plane_strain: expected one of \"none\", \"x\", \"y\", \"z\", got \"q\""),
      std::string::npos)
      << e;
}

TEST(CaseFile, MissingRequiredKey) {
  std::string e = error_of(edit("L = 0.01\n", ""));
  EXPECT_NE(e.find("lattice.L: missing required key"), std::string::npos) << e;
  e = error_of(edit("e_p = 1e-4\n", ""));
  EXPECT_NE(e.find("material.e_p: missing: give e_p or R_f"), std::string::npos) << e;
  e = error_of(edit("[time]\nend = 1e-4\n", ""));
  EXPECT_NE(e.find("time: missing required table [time]"), std::string::npos) << e;
}

TEST(CaseFile, UnknownNodeSetName) {
  const std::string e = error_of(edit("set = \"top\"", "set = \"tops\""));
  EXPECT_NE(e.find("velocity[0].set: expected the name of a [[node_set]], got \"tops\""),
            std::string::npos)
      << e;
}

TEST(CaseFile, BadTimeFunctionTerm) {
  std::string e =
      error_of(edit("{ type = \"ramp\", duration = 1e-4 }", "{ type = \"ramp\" }"));
  EXPECT_NE(e.find("velocity[0].function[0].duration: required for a \"ramp\" term"),
            std::string::npos)
      << e;  // A table's points must be pairs with times that increase; keys of other terms are refused.
  const std::string ramp = "{ type = \"ramp\", duration = 1e-4 }";
  e = error_of(edit(ramp, "{ type = \"table\", points = [[0, 0], [1e-4, 1], [1e-4, 2]] }"));
  EXPECT_NE(e.find("velocity[0].function[0].points[2]: expected times that increase, got s = "
                   "0.0001 after s = 0.0001"),
            std::string::npos)
      << e;
  e = error_of(edit(ramp, "{ type = \"table\", points = [[0, 0], [1e-4]] }"));
  EXPECT_NE(e.find("velocity[0].function[0].points[1]: expected a point [s, value] of two "
                   "numbers"),
            std::string::npos)
      << e;
  e = error_of(edit(ramp, "{ type = \"table\", points = [[0, 0]], duration = 1e-4 }"));
  EXPECT_NE(e.find("velocity[0].function[0].duration: does not apply to a \"table\" term"),
            std::string::npos)
      << e;
  e = error_of(edit(ramp, "{ type = \"ramp\", duration = 1e-4, t_start = 2e-4, t_end = 1e-4 }"));
  EXPECT_NE(e.find("velocity[0].function[0].t_end: expected a time after t_start = 0.0002, got "
                   "0.0001"),
            std::string::npos)
      << e;
  EXPECT_EQ(error_of(edit(ramp, "{ type = \"table\", points = [[0, 0], [1e-4, 1]], t_end = 1 }")),
            "");
}

TEST(CaseFile, MissingFileIsNamed) {
  try {
    read_case("/nonexistent/case.toml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/case.toml: cannot read the case file"),
              std::string::npos);
  }
}

// Every declared key appears in the generated reference, with its unit and default.
TEST(CaseFile, FormatReferenceListsEveryKey) {
  const std::string md = case_format_markdown();
  for (const KeyDecl& k : case_keys())
    EXPECT_NE(md.find(std::string("| `") + k.key + "` | " + k.type + " | " + k.fallback + " | " +
                      k.unit + " |"),
              std::string::npos)
        << k.table << "." << k.key;
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

TEST(CaseFile, MaterialFieldsParse) {
  std::string text = kGood;
  text.replace(text.find("e_p = 1e-4"), 10,
               "e_p = { type = \"linear\", axis = \"z\", values = [1e-4, 3e-4] }\n"
               "Gf = { type = \"weibull\", mean = 100.0, cv = 0.1, seed = 3 }");
  text.replace(text.find("Gf = 100\n"), 9, "");
  const CaseSpec c = parse_case(text, "case.toml");
  ASSERT_TRUE(c.fields.e_p.has_value());
  EXPECT_EQ(c.fields.e_p->kind, Field::Kind::Linear);
  // Without `at`, the grading spans the body: z from 0 to nz L = 0.04 m.
  EXPECT_DOUBLE_EQ(c.fields.e_p->table.back().first, 0.04);
  EXPECT_DOUBLE_EQ(c.material.e_p.value(), 2e-4); // representative: mean of the two values
  ASSERT_TRUE(c.fields.Gf.has_value());
  EXPECT_EQ(c.fields.Gf->seed, 3u);
  EXPECT_DOUBLE_EQ(c.material.Gf, 100.0);
}

TEST(CaseFile, BadFieldIsNamed) {
  const std::string e =
      error_of(edit("Gf = 100", "Gf = { type = \"weibul\", mean = 100.0, cv = 0.1 }"));
  EXPECT_NE(e.find("material.Gf.type: expected one of \"linear\", \"table\", \"weibull\", got "
                   "\"weibul\""),
            std::string::npos)
      << e;
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// Found by fuzzing: a non-ASCII character in a number reached undefined behaviour inside the
// TOML parser; such characters are refused outside strings and comments, with the line.
TEST(CaseFile, NonAsciiOutsideStringsIsRefused) {
  const std::string e = error_of(edit("L = 0.01", "L = 0.0\xd0\x9a"));
  EXPECT_NE(e.find("case.toml:4: malformed TOML: a non-ASCII character outside a string or "
                   "comment"),
            std::string::npos)
      << e;
  // In comments and strings they are fine.
  EXPECT_NO_THROW(parse_case(edit("L = 0.01", "L = 0.01 # \xc3\xa9paisseur"), "case.toml"));
  const std::string nul = error_of(edit("L = 0.01", std::string("L = 0.01\0", 9)));
  EXPECT_NE(nul.find("control character (byte 0)"), std::string::npos) << nul;
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// The analyses are refused before a run when the case cannot give them what they measure.
TEST(CaseFile, FatigueAnalysisNeedsAPrecrackAndACyclicLoad) {
  std::string e = error_of(kGood + std::string("\n[analysis]\nfatigue = true\n"));
  EXPECT_NE(e.find("analysis.fatigue: expected a case with a [[precrack]]"), std::string::npos)
      << e;
  const std::string cracked = kGood + std::string(R"(
[[precrack]]
name = "notch"
origin = [-0.001, -0.001, 0.0225]
edge1 = [0.02, 0.0, 0.0]
edge2 = [0.0, 0.012, 0.0]

[[load]]
name = "pull"
set = "top"
force = [0.0, 0.0, 10.0]
function = [{ type = "exp_rise", tau = 1e-5 }]
)");
  e = error_of(cracked + "\n[analysis]\nfatigue = true\n");
  EXPECT_NE(e.find("analysis.fatigue: expected a [[load]] whose function has a \"growing_sine\" "
                   "term"),
            std::string::npos)
      << e;
  e = error_of(cracked + "\n[analysis]\nfatigue = true\nfatigue_load = \"pul\"\n");
  EXPECT_NE(e.find("analysis.fatigue_load: expected the name of a [[load]], got \"pul\""),
            std::string::npos)
      << e;
  e = error_of(cracked + "\n[analysis]\nfatigue = true\nfatigue_points = 2\n");
  EXPECT_NE(e.find("analysis.fatigue_points"), std::string::npos) << e;
}

} // namespace
} // namespace ldem

#include "app/case_run.hpp"

#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <unistd.h>

namespace ldem {
namespace {

// The case file of the running test: ldem_conditions_case.toml in a folder of its own (the
// tests run in parallel processes, and a shared file would be rewritten under another's feet).
std::string test_case_path() {
  const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) /
                                    fmt::format("ldem_{}_{}", test->name(), ::getpid());
  std::filesystem::create_directories(dir);
  return (dir / "ldem_conditions_case.toml").string();
}

// The message build_case gives for a case text (written to a file), or "" if it accepts it.
std::string build_error_of(const std::string& text) {
  const std::string path = test_case_path();
  std::ofstream(path) << text;
  try {
    build_case(path, nullptr, false);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Conditions that contradict each other are refused before a run, with the tables, their node
// sets, the DOF, the count of nodes and the first of them. The good case's top face has
// (4 + 1) x (1 + 1) = 10 corner nodes, the first of them node 40 (corner (0, 0, 4)) at
// z = 4 x 0.01 m.
TEST(CaseFile, ConditionsThatContradictEachOtherAreRefused) {
  ASSERT_EQ(build_error_of(kGood), "");
  // Two velocities on the same DOF of the same nodes.
  std::string e = build_error_of(kGood + R"(
[[velocity]]
set = "top"
dofs = "z"
value = [0, 0, -0.01]
)");
  // The error is placed at the second table's dofs key: kGood's lines, a blank line, the
  // header, set, dofs.
  const long second = std::count(kGood.begin(), kGood.end(), '\n') + 4;
  EXPECT_NE(e.find(fmt::format("ldem_conditions_case.toml:{}: velocity[1].dofs: [[velocity]] "
                               "tables 1 (node set \"top\") and 2 (node set \"top\") both impose "
                               "the z velocity on 10 nodes (the first: node 40 at (0, 0, 0.04) m)",
                               second)),
            std::string::npos)
      << e;
  // A DOF both held and driven.
  e = build_error_of(kGood + R"(
[[fixed]]
set = "top"
dofs = "xz"
)");
  EXPECT_NE(e.find("[[velocity]] table 1 (node set \"top\") imposes the z velocity on 10 nodes "
                   "that [[fixed]] table 1 (node set \"top\") holds (the first: node 40"),
            std::string::npos)
      << e;
  // Plane strain holds y; a velocity that drives y contradicts it.
  e = build_error_of(edit("dofs = \"z\"", "dofs = \"yz\""));
  EXPECT_NE(e.find("[[velocity]] table 1 (node set \"top\") imposes the y velocity on its 10 "
                   "nodes, but plane_strain = \"y\" holds y at every node"),
            std::string::npos)
      << e;
  // What does not contradict: two velocities on other DOF of the same nodes, a fixed DOF that
  // no velocity drives, one that plane strain also holds.
  EXPECT_EQ(build_error_of(kGood + R"(
[[fixed]]
set = "top"
dofs = "y"

[[velocity]]
set = "top"
dofs = "x"
value = [0.01, 0, 0]
)"),
            "");
}

// Errors found only once the body is built carry the line of the table entry they concern.
// kGood's lines, then a blank line: the appended entry's header is two lines further.
TEST(CaseFile, ErrorsFoundOnTheBuiltBodyNameTheEntrysLine) {
  const long header = std::count(kGood.begin(), kGood.end(), '\n') + 2;
  // A pre-crack beside the 0.04 m body crosses no bar.
  std::string e = build_error_of(kGood + R"(
[[precrack]]
name = "away"
origin = [1.0, -0.001, 0.02]
edge1 = [0.01, 0, 0]
edge2 = [0, 0.02, 0]
)");
  EXPECT_NE(e.find(fmt::format("ldem_conditions_case.toml:{}: precrack[0]: pre-crack \"away\" "
                               "crosses no bar",
                               header)),
            std::string::npos)
      << e;
  // A box beside the body selects no node; the node set is the second, after "top".
  e = build_error_of(kGood + R"(
[[node_set]]
name = "nothing"
box_min = [1, 1, 1]
box_max = [2, 2, 2]
)");
  EXPECT_NE(e.find(fmt::format("ldem_conditions_case.toml:{}: node_set[1]: node set \"nothing\" "
                               "(box [1, 1, 1] to [2, 2, 2]) selects no node",
                               header)),
            std::string::npos)
      << e;
  // A fatigue box beside the body holds no bar's centre.
  e = build_error_of(edit("e_p = 1e-4", "e_p = 1e-4\nlaw = \"bilinear_fatigue\"") + R"(
[fatigue]
A = 1e10
m = 4
box_min = [1, 1, 1]
box_max = [2, 2, 2]
)");
  EXPECT_NE(e.find("fatigue.box_min: expected a box that at least one bar meets, got "
                   "[1, 1, 1] to [2, 2, 2] m"),
            std::string::npos)
      << e;
  // A rupture strain field that falls to e_p along x is found on the bars; the error names the
  // [material] table's line (line 7 of kGood: a blank first line, four lines of [lattice], a
  // blank line).
  const std::string path = test_case_path();
  std::ofstream(path) << edit(
      "e_p = 1e-4", "e_p = 1e-4\ne_r = { type = \"linear\", axis = \"x\", values = [1e-4, 1e-3] }");
  e.clear();
  try {
    build_case(path); // the bars' values are found only where the simulation is built
  } catch (const InputError& x) {
    e = x.what();
  }
  EXPECT_NE(e.find("ldem_conditions_case.toml:7: material: bar "), std::string::npos) << e;
  EXPECT_NE(e.find("expected e_r > e_p"), std::string::npos) << e;
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// A step above the proven stable bound (Gershgorin) but below the Lanczos estimate is run, with
// a warning that says by how much it exceeds the bound and what step is stable for certain; a
// step below the bound has none. The bound lies below the estimate (it bounds the largest
// eigenfrequency from above).
TEST(CaseFile, TimeStepAboveTheProvenBoundIsWarned) {
  const std::string path = ::testing::TempDir() + "ldem_step_case.toml";
  std::ofstream(path) << kGood;
  const BuiltCase c = build_case(path);
  const BodyNumbers b = body_numbers(*c.sim);
  ASSERT_LT(b.stable.dt_bound, b.stable.dt);
  const double dt = std::sqrt(b.stable.dt_bound * b.stable.dt); // between the two
  std::ofstream(path) << edit("end = 1e-4",
                              fmt::format("end = 1e-4\nrule = \"dt\"\ndt = {:.17g}", dt));
  const BuiltCase above = build_case(path);
  const BodyNumbers n = body_numbers(*above.sim);
  ASSERT_EQ(n.dt, dt);
  const std::optional<std::string> w = time_step_warning(n);
  ASSERT_TRUE(w.has_value());
  EXPECT_NE(w->find(fmt::format("is {:.0f} % above {:.4g} s",
                                100.0 * (dt / n.stable.dt_bound - 1.0), n.stable.dt_bound)),
            std::string::npos)
      << *w;
  EXPECT_NE(resolved_case_toml(above, n).find("warnings = ["), std::string::npos);
  std::ofstream(path) << edit("end = 1e-4", fmt::format("end = 1e-4\nsafety = {:.6f}",
                                                        0.99 * b.stable.dt_bound / b.stable.dt));
  const BuiltCase below = build_case(path);
  EXPECT_FALSE(time_step_warning(body_numbers(*below.sim)).has_value());
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// The paper's step rule takes the fastest bar wave speed, sqrt(E / rho) at the largest E and the
// smallest density. A density graded from 1200 to 2400 kg/m^3 across the 4 modules of the good
// case's height, taken at module centres, is 1350 kg/m^3 at its lightest (1200 + 1200 / 8), so
// dt = 0.5 L / sqrt(30e9 / 1350); with the mean density, 1800, the step would be sqrt(4/3) =
// 1.15 times longer than the wave speed of the light modules allows.
TEST(CaseFile, PaperStepRuleTakesTheFastestWaveSpeed) {
  const std::string path = ::testing::TempDir() + "ldem_paper_rule_case.toml";
  std::string text = edit("rho = 2400", "rho = { type = \"linear\", axis = \"z\", values = "
                                        "[1200.0, 2400.0] }");
  text.replace(text.find("end = 1e-4"), 10, "end = 1e-4\nrule = \"paper\"\ncourant = 0.5");
  std::ofstream(path) << text;
  const BuiltCase c = build_case(path);
  EXPECT_NEAR(c.sim->dt(), 0.5 * 0.01 / std::sqrt(30e9 / 1350.0), 1e-12 * c.sim->dt());
}

} // namespace
} // namespace ldem

#include "analysis/fatigue.hpp"

namespace ldem {
namespace {

// A traction load [Pa] on a face weighs each node by the area it stands for. The good case's
// top face, 4 x 1 modules of L = 0.01 m, has 5 x 2 corner nodes: the 4 at its corners stand
// for L^2 / 4 each, the 6 others (all on its border, the plate being one module thick) for
// L^2 / 2: 4 L^2 = 4e-4 m^2 in all, the face's area. A traction of 2 MPa there is a force of
// 800 N, which is what a probe of the load records; the fatigue analysis takes the traction
// itself as the remote stress. A force of 1000 N per node on the same 10 nodes is 10 kN over
// the plate's section normal to z, 0.04 m x 0.01 m: 25 MPa.
TEST(CaseFile, TractionLoadActsOnTheAreaOfItsFace) {
  const std::string path = ::testing::TempDir() + "ldem_traction_case.toml";
  const std::string load = R"(
[[node_set]]
name = "bottom"
face = "z-"

[[node_set]]
name = "block"
box_min = [0, 0, 0]
box_max = [0.01, 0.01, 0.01]

[[fixed]]
set = "bottom"

[[load]]
name = "pull"
set = "top"
traction = [0, 0, 2e6]
)";
  std::ofstream(path) << edit("dofs = \"z\"", "dofs = \"x\"") + load;
  const BuiltCase c = build_case(path);
  double area = 0.0;
  for (double a : c.conditions.loads[0].weight)
    area += a;
  EXPECT_NEAR(area, 4e-4, 1e-18);
  EXPECT_NEAR(load_total_force(c, 0, 0.0), 800.0, 1e-10);
  RunGeometry rg;
  rg.case_file = path;
  rg.extent = {0.04, 0.01, 0.04};
  rg.resolved = toml::parse(resolved_case_toml(c, body_numbers(*c.sim)));
  const toml::table& pull = *rg.resolved["load"][0].as_table();
  EXPECT_NEAR(pull["area"].value_or(0.0), 4e-4, 1e-18);
  EXPECT_DOUBLE_EQ(load_remote_stress(rg, pull), 2e6);

  // A force per node: its total is the force times the nodes; its remote stress the total
  // over the section.
  const std::string traction_case = edit("dofs = \"z\"", "dofs = \"x\"") + load;
  std::ofstream(path) << std::string(traction_case)
                             .replace(traction_case.find("traction = [0, 0, 2e6]"), 22,
                                      "force = [0, 0, 1000]");
  const BuiltCase f = build_case(path);
  EXPECT_NEAR(load_total_force(f, 0, 0.0), 1e4, 1e-9);
  rg.resolved = toml::parse(resolved_case_toml(f, body_numbers(*f.sim)));
  EXPECT_NEAR(load_remote_stress(rg, *rg.resolved["load"][0].as_table()), 2.5e7, 1e-6);

  // Any other set: the body's surface it covers. The box around the corner module's nodes
  // covers that module's x- and z- faces (its y faces are not surface: the plate is one module
  // thick, a slice in plane strain): 2 L^2.
  const std::string on_box =
      std::string(traction_case)
          .replace(traction_case.find("set = \"top\"\ntraction"), 11, "set = \"block\"");
  std::ofstream(path) << on_box;
  const BuiltCase b = build_case(path);
  area = 0.0;
  for (double a : b.conditions.loads[0].weight)
    area += a;
  EXPECT_NEAR(area, 2e-4, 1e-18);
  // Refused: a traction on a set that covers none of the surface, two ways to give the force,
  // none.
  const std::string on_node =
      std::string(traction_case)
          .replace(traction_case.find("set = \"top\"\ntraction"), 11, "set = \"node\"") +
      "\n[[node_set]]\nname = \"node\"\nbox_min = [0.02, 0, 0.02]\nbox_max = [0.02, 0, 0.02]\n";
  std::string e = build_error_of(on_node);
  EXPECT_NE(e.find("load[0].traction: load \"pull\" has a traction: expected a node set that "
                   "covers some of the body's surface (the four corners of a module face on it), "
                   "got \"node\", box"),
            std::string::npos)
      << e;
  e = build_error_of(edit("dofs = \"z\"", "dofs = \"x\"") + load + "force = [0, 0, 1]\n");
  EXPECT_NE(e.find("load[0].traction"), std::string::npos) << e;
  EXPECT_NE(e.find("expected one of force, traction, total and acceleration, got force and "
                   "traction"),
            std::string::npos)
      << e;
  e = build_error_of(
      std::string(traction_case).replace(traction_case.find("traction = [0, 0, 2e6]"), 22, ""));
  EXPECT_NE(e.find("expected force (N on each node), traction (Pa on a surface), total (N over a "
                   "surface) or acceleration (m/s^2 on each node's mass)"),
            std::string::npos)
      << e;
}

// Node sets by shape, on the good case's 4 x 1 x 4 modules of L = 0.01 m (corners at
// multiples of L, y = 0 and 0.01; centres at odd multiples of L/2, y = 0.005):
// - a sphere of radius L about the corner (0.02, 0, 0.02): the corner itself, its neighbours
//   along +-x, +-z and +y (none below y = 0), 6 corners, and the 4 centres around it at
//   L sqrt(3) / 2: 10 nodes;
// - a thin cylinder along y through the centre of module (1, 0, 1): that centre alone;
// - the half-space z >= 0.035 m: the 5 x 2 corners of the top face and the 4 centres of the
//   top row of modules at z = 0.035 (on the plane, taken): 14 nodes;
// - a box 0.04 m along x and 1 mm along z about (0.02, 0.0005), turned by 90 degrees about y:
//   1 mm along x and 0.04 m along z about that point, which holds the corners at x = 0.02 and
//   z = 0, 0.01 and 0.02 (y = 0 and 0.01): 6 nodes.
TEST(CaseFile, NodeSetsByShapeTakeTheNodesInside) {
  const std::string path = test_case_path();
  const std::string sets = R"(
[[node_set]]
name = "ball"
shape = { type = "sphere", centre = [0.02, 0, 0.02], radius = 0.01 }

[[node_set]]
name = "pin"
shape = { type = "cylinder", start = [0.015, -1, 0.015], end = [0.015, 1, 0.015], radius = 0.001 }

[[node_set]]
name = "upper"
shape = { type = "half_space", point = [0, 0, 0.035], normal = [0, 0, 2] }

[[node_set]]
name = "turned"
shape = { type = "box", min = [0, -1, 0], max = [0.04, 1, 0.001], axis = "y", angle = 90 }
)";
  std::ofstream(path) << kGood + sets;
  const BuiltCase c = build_case(path);
  auto count = [&](const std::string& name) {
    for (const NodeSet& s : c.sets)
      if (s.name == name)
        return s.nodes.size();
    return std::size_t{0};
  };
  EXPECT_EQ(count("ball"), 10u);
  EXPECT_EQ(count("pin"), 1u);
  EXPECT_EQ(count("upper"), 14u);
  EXPECT_EQ(count("turned"), 6u);
  // The resolved case gives the shape back as the case gave it, and the count.
  const toml::table resolved = toml::parse(resolved_case_toml(c, body_numbers(*c.sim)));
  const toml::table& ball = *resolved["node_set"][1].as_table();
  EXPECT_EQ(ball["shape"]["type"].value_or(std::string()), "sphere");
  EXPECT_DOUBLE_EQ(ball["shape"]["radius"].value_or(0.0), 0.01);
  EXPECT_EQ(ball["nodes_selected"].value_or(0), 10);
  EXPECT_DOUBLE_EQ(resolved["node_set"][4]["shape"]["angle"].value_or(0.0), 90.0);
}

// Bad shapes are refused with the key and what was expected.
TEST(CaseFile, BadShapesAreRefused) {
  auto with = [](const std::string& shape) {
    return error_of(kGood + "\n[[node_set]]\nname = \"s\"\nshape = " + shape + "\n");
  };
  EXPECT_NE(with(R"({ type = "cone", centre = [0, 0, 0] })")
                .find("node_set[1].shape.type: expected one of \"box\", \"cylinder\""),
            std::string::npos)
      << with(R"({ type = "cone" })");
  EXPECT_NE(with(R"({ type = "sphere", centre = [0, 0, 0] })")
                .find("node_set[1].shape.radius: missing: a \"sphere\" shape needs radius"),
            std::string::npos);
  EXPECT_NE(with(R"({ type = "cylinder", start = [0, 0, 0], end = [0, 0, 0], radius = 1 })")
                .find("node_set[1].shape.end: expected an end apart from start"),
            std::string::npos);
  EXPECT_NE(with(R"({ type = "box", min = [0, 0, 0], max = [1, 1, 1], axis = "y" })")
                .find("node_set[1].shape.angle: missing: axis needs angle"),
            std::string::npos);
  EXPECT_NE(with(R"({ type = "box", min = [0, 0, 0], max = [1, 1, 1], centre = [0, 0, 0] })")
                .find("node_set[1].shape.centre: does not apply to a \"box\" shape"),
            std::string::npos);
  EXPECT_NE(with(R"({ type = "box", min = [0, 0, 0], max = [1, -1, 1] })")
                .find("node_set[1].shape.max: expected a corner at or above min"),
            std::string::npos);
  EXPECT_NE(with(R"({ type = "half_space", point = [0, 0, 0], normal = [0, 0, 0] })")
                .find("node_set[1].shape.normal: expected a vector that is not zero"),
            std::string::npos);
  EXPECT_NE(with(R"("sphere")").find("node_set[1].shape: expected a shape"), std::string::npos);
  EXPECT_NE(with(R"({ type = "sphere", centre = [0, 0, 0], radius = -1 })")
                .find("node_set[1].shape.radius"),
            std::string::npos);
}

// [[geometry]]: a body cut from the box, a mask of modules from a .npy file beside the case
// (a relative path is from the case's folder), the surface of the body as a node set, and the
// resolved case's account of it.
TEST(CaseFile, GeometryShapesTheBody) {
  const std::string path = test_case_path();
  // A 4 x 1 x 4 plate with the module (1, 0, 1) removed by a mask and the column x >= 0.03
  // above z = 0.02 removed by a box.
  {
    std::string npy("\x93NUMPY\x01\x00", 8);
    std::string header = "{'descr': '|u1', 'fortran_order': False, 'shape': (4, 1, 4), }";
    header.append(128 - 10 - header.size() - 1, ' ');
    header += '\n';
    npy += static_cast<char>(header.size());
    npy += '\0';
    npy += header;
    for (int i = 0; i < 4; ++i)
      for (int k = 0; k < 4; ++k)
        npy += static_cast<char>(i == 1 && k == 1 ? 0 : 1);
    std::ofstream(std::filesystem::path(path).parent_path() / "plate.npy", std::ios::binary) << npy;
  }
  const std::string geometry = R"(
[[geometry]]
add = { type = "npy", file = "plate.npy" }

[[geometry]]
remove = { type = "box", min = [0.03, -1, 0.02], max = [1, 1, 1] }

[[node_set]]
name = "skin"
shape = { type = "box", min = [-1, -1, -1], max = [1, 1, 1] }
surface = true
)";
  std::ofstream(path) << kGood + geometry;
  const BuiltCase c = build_case(path);
  const Lattice& lat = c.sim->lattice();
  ASSERT_TRUE(lat.shaped());
  EXPECT_EQ(lat.num_present_modules(), 16u - 1 - 2);
  EXPECT_FALSE(lat.module_present(1, 0, 1));
  EXPECT_FALSE(lat.module_present(3, 0, 3));
  // The top face's corners: x in [0, 0.03] (i = 0..3), both y: 8.
  EXPECT_EQ(set_named(c.sets, "top").nodes.size(), 8u);
  // The plate is one module thick along y: its faces across are no surface. Per j, of the 5 x 5
  // corners (i, k): the outline on the box's faces, 14 ((0, 0..4), (1..4, 0), (4, 1..2),
  // (1..3, 4); (4, 3) and (4, 4) are absent), the removed column's side (3, 2) and (3, 3), and
  // the 4 corners of the masked module (1, 0, 1): 20.
  EXPECT_EQ(set_named(c.sets, "skin").nodes.size(), 2u * 20);
  const toml::table resolved = toml::parse(resolved_case_toml(c, body_numbers(*c.sim)));
  EXPECT_EQ(resolved["geometry"][0]["add"]["type"].value_or(std::string()), "npy");
  EXPECT_EQ(resolved["geometry"][0]["add"]["file"].value_or(std::string()), "plate.npy");
  EXPECT_EQ(resolved["geometry"][1]["remove"]["type"].value_or(std::string()), "box");
  EXPECT_EQ(resolved["lattice"]["modules_present"].value_or(0), 13);
  EXPECT_EQ(resolved["resolved"]["bars"].value_or(std::int64_t{0}),
            static_cast<std::int64_t>(lat.num_present_bars()));
  EXPECT_DOUBLE_EQ(resolved["lattice"]["volume"].value_or(0.0), 13 * 1e-6);
}

// A geometry that keeps the whole box is the box: the lattice is not shaped, and the run is
// the box's, byte for byte.
TEST(CaseFile, AGeometryThatKeepsTheBoxIsTheBox) {
  const std::string path = test_case_path();
  std::ofstream(path) << kGood + R"(
[[geometry]]
remove = { type = "sphere", centre = [5, 5, 5], radius = 0.1 }
)";
  const BuiltCase c = build_case(path);
  EXPECT_FALSE(c.sim->lattice().shaped());
}

// Bad geometry is refused with the key and what was expected.
TEST(CaseFile, BadGeometryIsRefused) {
  EXPECT_NE(error_of(kGood + "\n[[geometry]]\nadd = { type = \"sphere\", centre = [0, 0, 0], "
                             "radius = 1 }\nremove = { type = \"sphere\", centre = [0, 0, 0], "
                             "radius = 1 }\n")
                .find("geometry[0].add: expected exactly one of add"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + "\n[[geometry]]\nremove = { type = \"npy\" }\n")
                .find("geometry[0].remove.file: missing"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + "\n[[geometry]]\nremove = { type = \"npy\", file = \"nope.npy\" }\n")
                .find("geometry[0].remove.file: "),
            std::string::npos);
  EXPECT_NE(error_of(kGood + "\n[[node_set]]\nname = \"m\"\nshape = { type = \"npy\", file = "
                             "\"a.npy\" }\n")
                .find("node_set[1].shape.type: expected \"box\", \"cylinder\", \"sphere\" or "
                      "\"half_space\" (a mask of modules"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + "\n[[node_set]]\nname = \"f\"\nface = \"x-\"\nsurface = true\n")
                .find("node_set[1].surface: surface = true applies to a node set given by shape"),
            std::string::npos);
  // Removing every module leaves no body.
  EXPECT_NE(build_error_of(kGood + "\n[[geometry]]\nremove = { type = \"box\", min = [-1, -1, "
                                   "-1], max = [1, 1, 1] }\n")
                .find("geometry"),
            std::string::npos);
}

// [[region]]: the bars whose centres lie inside a region take its properties (numbers or
// fields), the modules inside it its density; a later region wins; distributed windows get the
// same values (case_fields for a list of bars).
TEST(CaseFile, RegionsGiveTheirMaterialInsideTheirShapes) {
  const std::string path = test_case_path();
  std::ofstream(path) << kGood + R"(
[[region]]
shape = { type = "box", min = [0, -1, 0], max = [0.02, 1, 0.02] }
E = 60e9
Gf = { type = "weibull", mean = 200.0, cv = 0.1, seed = 3 }
rho = 3000

[[region]]
shape = { type = "box", min = [0, -1, 0], max = [0.01, 1, 0.01] }
E = 10e9
)";
  const BuiltCase c = build_case(path);
  const Lattice& lat = c.sim->lattice();
  const BarTable& table = c.sim->table();
  ASSERT_TRUE(table.per_bar());
  const double tol = 1e-9 * lat.L();
  std::size_t in_first = 0, in_second = 0;
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const Vec3 x = lat.bar_centre(b);
    const bool second = x.x <= 0.01 + tol && x.z <= 0.01 + tol;
    const bool first = x.x <= 0.02 + tol && x.z <= 0.02 + tol;
    const BarTable::Properties p = table.properties(lat, b);
    if (second) {
      EXPECT_NEAR(p.E, 10e9, 1e-6 * 10e9) << b;
      ++in_second;
    } else if (first) {
      EXPECT_NEAR(p.E, 60e9, 1e-6 * 60e9) << b;
      ++in_first;
    } else {
      EXPECT_NEAR(p.E, 30e9, 1e-6 * 30e9) << b;
      EXPECT_NEAR(p.Gf, 100.0, 1e-6 * 100.0) << b; // e_p given, Gf as [material] gives it
    }
  }
  EXPECT_GT(in_first, 0u);
  EXPECT_GT(in_second, 0u);
  // The Weibull Gf inside the first region varies bar by bar about its mean.
  const BarFields f = case_fields(c.spec, lat, nullptr, nullptr);
  ASSERT_EQ(f.Gf.size(), lat.num_bars());
  double lo = INFINITY, hi = 0.0;
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const Vec3 x = lat.bar_centre(b);
    if (x.x <= 0.02 + tol && x.z <= 0.02 + tol) {
      lo = std::min(lo, f.Gf[b]);
      hi = std::max(hi, f.Gf[b]);
    } else {
      EXPECT_EQ(f.Gf[b], 100.0);
    }
  }
  EXPECT_LT(lo, 200.0);
  EXPECT_GT(hi, 200.0);
  // The same values for a list of bars (a window's): bar by bar.
  const std::vector<index_t> some = {0, 7, lat.num_bars() / 2, lat.num_bars() - 1};
  const std::vector<index_t> modules = {0, 5, 15};
  const BarFields g = case_fields(c.spec, lat, &some, &modules);
  for (std::size_t q = 0; q < some.size(); ++q) {
    EXPECT_EQ(g.E[q], f.E[some[q]]);
    EXPECT_EQ(g.Gf[q], f.Gf[some[q]]);
  }
  // Densities: the 2 x 2 modules in the first region's box at 3000, the rest 2400; the masses
  // sum to rho V over the modules.
  ASSERT_EQ(f.rho.size(), lat.num_modules());
  EXPECT_EQ(g.rho[0], 3000.0);
  EXPECT_EQ(g.rho[1], 3000.0); // module (1, 0, 1)
  EXPECT_EQ(g.rho[2], 2400.0); // module (3, 0, 3)
  double mass = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    mass += c.sim->mass(n);
  const double V = lat.L() * lat.L() * lat.L();
  EXPECT_NEAR(mass, (4 * 3000.0 + 12 * 2400.0) * V, 1e-12 * mass);
  const toml::table resolved = toml::parse(resolved_case_toml(c, body_numbers(*c.sim)));
  EXPECT_DOUBLE_EQ(resolved["region"][1]["E"].value_or(0.0), 10e9);
  EXPECT_EQ(resolved["region"][0]["shape"]["type"].value_or(std::string()), "box");
}

// A region's properties follow [material]'s rule, and a region must give one.
TEST(CaseFile, RegionsFollowTheMaterialsRule) {
  const std::string box =
      "\n[[region]]\nshape = { type = \"sphere\", centre = [0, 0, 0], radius = 0.01 }\n";
  EXPECT_NE(error_of(kGood + box + "R_f = 1.0\n").find("region[0].R_f: [material] gives e_p"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + box + "e_r = 1e-3\n").find("region[0].e_r: [material] gives no e_r"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + box).find("region[0].shape: a region gives no property"),
            std::string::npos);
  EXPECT_NE(error_of(kGood + box + "nu = 0.2\n").find("region[0].nu"), std::string::npos);
  EXPECT_NE(error_of(kGood + "\n[[region]]\nE = 1e9\n").find("region[0].shape"), std::string::npos);
}

// A pre-crack across a shaped body cuts its present bars only (the box's bars in a hole have no
// stiffness to cut), and the resolved case counts those.
TEST(CaseFile, APrecrackAcrossAHoleCutsPresentBarsOnly) {
  const std::string path = test_case_path();
  std::ofstream(path) << kGood + R"(
[[geometry]]
remove = { type = "box", min = [0.0, -1, 0.0], max = [0.02, 1, 0.04] }

[[precrack]]
name = "cut"
origin = [-0.001, -0.001, 0.0225]
edge1 = [0.05, 0.0, 0.0]
edge2 = [0.0, 0.02, 0.0]
)";
  const BuiltCase c = build_case(path);
  const Lattice& lat = c.sim->lattice();
  ASSERT_FALSE(c.precracked.empty());
  for (const index_t b : c.precracked)
    EXPECT_TRUE(lat.bar_present(b)) << b;
  // The plane z = 0.0225 crosses the modules of layer k = 2; only the 2 columns x >= 0.02
  // are present there: their EdgeZ bars (3 x 2), centre bars from layer 1 to 2 (0: layer 1's
  // modules at i = 2, 3 are present, so 2), and the diagonals of the upper half (4 x 2).
  EXPECT_EQ(c.precracked.size(), 6u + 2 + 8);
}

// An STL surface in millimetres shapes the body ([[geometry]] type = "stl", scale = 0.001): the
// good case's 4 x 1 x 4 plate cut to the modules whose centres lie in a box (written as 12
// facets of an ASCII STL beside the case): 2 along x times 3 along z.
TEST(CaseFile, AnStlSurfaceShapesTheBody) {
  const std::string path = test_case_path();
  {
    std::ofstream f(std::filesystem::path(path).parent_path() / "block.stl");
    // mm: the centres 15 and 25 along x, 15 to 35 along z (to the top face, which the good case
    // pulls)
    const double lo[3] = {9, -5, 9}, hi[3] = {31, 15, 45};
    auto at = [&](int c) {
      return fmt::format("{} {} {}", (c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1],
                         (c & 4) ? hi[2] : lo[2]);
    };
    const int quads[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                             {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    f << "solid block\n";
    for (const auto& q : quads)
      for (const std::array<int, 3> tri :
           {std::array<int, 3>{q[0], q[1], q[2]}, std::array<int, 3>{q[0], q[2], q[3]}})
        f << "facet normal 0 0 0\nouter loop\nvertex " << at(tri[0]) << "\nvertex " << at(tri[1])
          << "\nvertex " << at(tri[2]) << "\nendloop\nendfacet\n";
    f << "endsolid block\n";
  }
  std::ofstream(path) << kGood + R"(
[[geometry]]
add = { type = "stl", file = "block.stl", scale = 0.001 }
)";
  const BuiltCase c = build_case(path);
  const Lattice& lat = c.sim->lattice();
  ASSERT_TRUE(lat.shaped());
  EXPECT_EQ(lat.num_present_modules(), 6u);
  EXPECT_TRUE(lat.module_present(1, 0, 1));
  EXPECT_TRUE(lat.module_present(2, 0, 3));
  EXPECT_FALSE(lat.module_present(0, 0, 0));
  const toml::table resolved = toml::parse(resolved_case_toml(c, body_numbers(*c.sim)));
  EXPECT_EQ(resolved["geometry"][0]["add"]["type"].value_or(std::string()), "stl");
  EXPECT_DOUBLE_EQ(resolved["geometry"][0]["add"]["scale"].value_or(0.0), 0.001);
}

} // namespace
} // namespace ldem
