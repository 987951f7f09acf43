// A case file (TOML) parsed once into typed structs. Every key is declared once in
// case_keys.cpp with its type, default, unit, range and help; the parser, the error messages
// and docs/case-format.md all come from those declarations.
#pragma once

#include "lattice/node_set.hpp"
#include "lattice/precrack.hpp"
#include "lattice/shape.hpp"
#include "material/bar_table.hpp"
#include "material/field.hpp"
#include "solver/simulation.hpp"
#include "solver/time_function.hpp"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

struct NodeSetSpec {
  std::string name;
  enum class Kind { Face, FaceCentres, Box, Shape, All } kind = Kind::All;
  Face face = Face::XMin;
  Vec3 lo, hi;
  ldem::Shape shape;    // Kind::Shape: every node inside it,
  bool surface = false; // or only the corner nodes of the body's surface inside it
};

// A material region: the properties it gives (numbers as constant fields) replace the
// [material]'s for the bars whose centres, and the modules (rho) whose centres, lie inside its
// shape; a later region wins where regions overlap.
struct RegionSpec {
  ldem::Shape shape;
  std::optional<Field> E, Gf, e_p, e_r, R_f, rho;
};

struct FixedSpec {
  std::string set;
  DofMask dofs = kDofAll;
};

// Loading controlled by a gauge probe ([[velocity]] control = {...}): the set moves at
// value * f, f in [-1, 1] set before each step so that the probe follows rate * t
// (docs/model.md, "Probe-controlled loading").
struct ControlSpec {
  std::string probe;          // a displacement, opening or strain probe
  double rate = 0.0;          // the probe's rate [its unit / s]
  double response_time = 0.0; // s (0: 20 times the time a bar wave takes to cross the body)
};

struct VelocitySpec {
  std::string set;
  DofMask dofs = kDofAll;
  Vec3 value;
  TimeFunction scale;
  std::optional<ControlSpec> control;
};

struct LoadSpec {
  std::string name, set;
  // What `force` is: N on every node (Force), Pa on the surface the set covers (Traction), N in
  // all over that surface (Total), or m/s^2 on every node's lumped mass (Acceleration).
  enum class Kind { Force, Traction, Total, Acceleration } kind = Kind::Force;
  Vec3 force;
  TimeFunction scale;
};

// A rigid platen ([[platen]]): a plane, or a cylinder for a roller or an indenter, moving at
// velocity * scale(t), pushing with a penalty spring and rubbing with Coulomb friction
// (solver's Platen; docs/model.md, "Platens").
struct PlatenSpec {
  std::string name;
  Platen::Kind kind = Platen::Kind::Plane;
  Vec3 point;
  Vec3 direction; // plane: its normal towards the body; cylinder: its axis (unit length)
  double radius = 0.0;
  Vec3 velocity;
  TimeFunction scale;
  double friction = 0.0;
  double penalty = 1.0; // the normal spring of a face node, in E L
};

struct PrecrackSpec {
  Rectangle rect;
  bool nudge = false;
};

struct ProbeSpec {
  std::string name;
  enum class Kind {
    BarForce,
    Reaction,
    Load,
    Displacement,
    Opening,
    Strain,
    Platen,
    PlatenDisplacement
  } kind = Kind::BarForce;
  Vec3 at;           // bar_force: the bar whose centre is nearest; displacement: the node
  bool has_at = false;
  std::string set;   // reaction: node set; displacement (without at): its nodes' mean
  int component = 2; // reaction, displacement, opening, platen: 0, 1, 2
  std::string load;  // load: name of the load
  std::string platen; // platen, platen_displacement: name of the platen
  // opening and strain: the two ends, each the node nearest a point or a node set's mean.
  struct End {
    std::optional<Vec3> point;
    std::string set;
  };
  End from, to;
};

struct OutputSpec {
  std::uint64_t energy_every = 0; // steps between energy rows (0: about 500 rows per run)
  std::uint64_t vtu_every = 0;    // steps between lattice snapshots (0: about 20 per run)
  bool vtu = true;
  bool plots = true;
  std::uint64_t checkpoint_every = 0; // steps between checkpoints (0: by wall time only)
  double checkpoint_seconds = 600.0;  // wall-clock seconds between checkpoints (0: never)
  bool end_checkpoint = true;         // a checkpoint of the last reported state at the end
  // The snapshots' optional arrays (vtu_array_names, io/output.hpp); empty: all of them.
  std::vector<std::string> vtu_arrays;
  bool vtu_zlib = false; // snapshots zlib-compressed (output.vtu_compression = "zlib")
};

// What `ldem run` analyses after the run ([analysis]); lengths 0 mean the default (in L).
struct AnalysisSpec {
  bool crack = false;
  double min_branch_length = 0.0; // m (0: 6 L)
  double branch_fit_length = 0.0; // m (0: 10 L)
  double speed_window = 0.0;      // s (0: 4 L / c_R)
  double speed_fit_length = 0.0;  // m (0: 10 L)
  double zone_flag_length = 0.0;  // m (0: 3 L)
  bool fatigue = false;
  std::string fatigue_load; // "" : the first load with a growing sine
  std::int64_t fatigue_points = 10;
  std::string fatigue_window = "constant"; // or "cycles"
  std::string fatigue_rate = "points";     // or "secant"
  double fatigue_fit_after = 0.0;          // m
  bool fatigue_fit_elastic = false;
  double fatigue_band = 0.0;             // m (0: a quarter of the body across the crack)
  double fatigue_unstable_advance = 0.0; // m (0: b / 10)
  double fatigue_width = 0.0;            // m (0: the body along the crack)
};

struct CaseSpec {
  std::string file; // the case file's path, for messages
  // The line of each key read ("time.damping", "probe[1].name"), for errors found after the
  // case is read (case_build: `located`).
  std::map<std::string, int> key_lines;
  std::string title;
  index_t nx = 0, ny = 0, nz = 0;
  double L = 0.0;
  int plane_strain_axis = -1;
  // The body's modules: the box, changed by these operations in order ([[geometry]]).
  std::vector<ShapeOp> geometry;
  std::vector<RegionSpec> regions; // [[region]], in order
  MaterialSpec material;
  std::string law = "bilinear"; // the bar law (solver/laws.cpp)
  // Properties given as fields (the MaterialSpec then holds a representative value).
  struct Fields {
    std::optional<Field> E, Gf, e_p, e_r, R_f, rho;
  } fields;
  std::vector<NodeSetSpec> node_sets;
  std::vector<FixedSpec> fixed;
  std::vector<VelocitySpec> velocities;
  std::vector<LoadSpec> loads;
  std::vector<PlatenSpec> platens;
  std::vector<PrecrackSpec> precracks;
  double end_time = 0.0;
  double stop_displacement = 0.0; // m; 0: none
  TimeStep step;
  double damping = 0.0;
  OutputSpec output;
  AnalysisSpec analysis;
  std::vector<ProbeSpec> probes;
};

// Reads and validates a case file. Throws InputError with "FILE:LINE: key: expected ...,
// got ..." (and a suggestion for a misspelt key).
CaseSpec read_case(const std::string& path);
// The same from text (for tests); `name` stands for the file in messages.
CaseSpec parse_case(const std::string& text, const std::string& name);

// One declared key: the documentation of the case format is generated from these.
struct KeyDecl {
  const char* table; // "lattice", "material", "node_set" (array of tables), ...
  const char* key;
  const char* type;     // "float", "integer", "string", "bool", "[3 floats]", ...
  const char* fallback; // the default as written in a case, "required", or "-" (optional)
  const char* unit;
  double lo, hi; // allowed range of numbers (and of array elements)
  bool lo_open, hi_open;
  const char* choices; // allowed strings, "" if any
  const char* help;
  std::string range_text() const;
};
const std::vector<KeyDecl>& case_keys();
// docs/case-format.md, generated from case_keys().
std::string case_format_markdown();

} // namespace ldem
