// The declaration of every case-file key, and the case-format documentation made from it.
#include "io/case_spec.hpp"

#include <cmath>
#include <fmt/format.h>
#include <limits>

namespace ldem {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kIdxMax = 4294967295.0;
} // namespace

std::string KeyDecl::range_text() const {
  if (*choices)
    return fmt::format("one of {}", choices);
  const bool has_lo = lo > -kInf, has_hi = hi < kInf;
  if (!has_lo && !has_hi)
    return "";
  if (has_lo && has_hi)
    return fmt::format("{}{:g}, {:g}{}", lo_open ? "(" : "[", lo, hi, hi_open ? ")" : "]");
  if (has_lo)
    return fmt::format("{} {:g}", lo_open ? ">" : ">=", lo);
  return fmt::format("{} {:g}", hi_open ? "<" : "<=", hi);
}

// clang-format off
const std::vector<KeyDecl>& case_keys() {
  static const std::vector<KeyDecl> keys = {
    // table, key, type, default, unit, lo, hi, lo open, hi open, choices, help
    {"case", "title", "string", "\"\"", "", -kInf, kInf, false, false, "", "A line that describes the case; copied to the outputs."},

    {"lattice", "modules", "[3 integers]", "required", "", 1, kIdxMax, false, false, "", "Modules along x, y and z (nx, ny, nz)."},
    {"lattice", "L", "float", "required", "m", 1e-9, 1e3, false, false, "", "Module edge (a nanometre to a kilometre)."},
    {"lattice", "plane_strain", "string", "\"none\"", "", -kInf, kInf, false, false, "\"none\", \"x\", \"y\", \"z\"", "Hold this displacement component at every node (plates one module thick)."},

    {"material", "law", "string", "\"bilinear\"", "", -kInf, kInf, false, false, "\"bilinear\", \"bilinear_fatigue\"", "Bar law: the paper's (eqs. 7-17), or the same with a fatigue life that strain cycles use up (needs a [fatigue] table; docs/model.md, \"Fatigue\")."},
    {"material", "E", "float or field", "required", "Pa", 1e-3, 1e15, false, false, "", "Young's modulus."},
    {"material", "nu", "float", "0.25", "", 0, 0.5, true, true, "", "Poisson's ratio; the lattice is isotropic only at 0.25 (other values give a warning)."},
    {"material", "rho", "float or field", "required", "kg/m^3", 1e-3, 1e6, false, false, "", "Density; as a field it is taken at module centres and lumped module by module."},
    {"material", "Gf", "float or field", "required", "N/m", 0, kInf, true, false, "", "Specific fracture energy. With e_p given, a field of Gf changes each bar's e_r (its K_r, eq. 12) and not its strength E A e_p, which stays as uniform as E and e_p; with R_f instead, e_p follows Gf bar by bar (eq. 7) and the strength varies too."},
    {"material", "e_p", "float or field", "-", "", 0, kInf, true, false, "", "Strain at peak force; give this or R_f."},
    {"material", "R_f", "float or field", "-", "m^-1/2", 0, kInf, true, false, "", "Failure factor: e_p = R_f sqrt(Gf / (E (1 - nu^2))) (eq. 7), per bar, so that a random Gf also makes the strength random."},
    {"material", "e_r", "float or field", "-", "", 0, kInf, true, false, "", "Strain at rupture of the normal bars; then each bar's Gf follows from eq. 11. Default: e_r = K_r e_p with K_r from eq. 12."},
    {"material", "single_ratio", "bool", "false", "", -kInf, kInf, false, false, "", "Use the paper's single A^f/A = 0.34 for both bar kinds (eq. 16)."},
    {"material", "allow_low_kr", "bool", "false", "", -kInf, kInf, false, false, "", "Run even where K_r < 1 (such bars break at e_p, brittle)."},

    {"fatigue", "A", "float", "required", "1/cycle", 0, kInf, true, false, "", "Life a cycle of tensile strain range 1 uses up in a bar of length `length`: a bar under cycles of range D breaks after 1 / (A D^m) of them. Bars of length l0 take A (l0 / length)^(m/2 - 1), which keeps Paris' C independent of L."},
    {"fatigue", "m", "float", "required", "", 0, 100, true, false, "", "Exponent of the strain range."},
    {"fatigue", "threshold", "float", "0", "", 0, kInf, false, false, "", "Half-cycles of strain range at or below it use no life."},
    {"fatigue", "gate", "float", "-", "", 0, kInf, true, false, "", "Default 1 % of the bar's e_p. A peak or valley of a bar's tensile strain counts once the strain has come back from it by more than this: smaller oscillations (ringing) are not cycles. Larger ones split a load cycle's range into smaller ranges: a fatigue run needs time.damping that takes the ringing of each break out within a load cycle (docs/model.md, \"Fatigue\")."},
    {"fatigue", "count_every", "integer", "10", "steps", 1, 1e6, false, false, "", "The strains are sampled for the count every this many steps: a turning point is found to within the strain's change over that many steps (time steps are far shorter than any load cycle; ringing is kept out by the gate)."},
    {"fatigue", "jump", "bool", "false", "", -kInf, kInf, false, false, "", "Cycle jumping, once the cyclic load has reached its constant amplitude (the end of its growing_sine's n_cycles): resolve jump_window cycles, take each bar's life used per cycle over them, and skip as many cycles as leave at most jump_breaks bars at the end of their life; then resolve again. energy.csv gains a column jumped_cycles."},
    {"fatigue", "jump_window", "integer", "4", "cycles", 1, 1e6, false, false, "", "Load cycles resolved between two jumps (the life each bar uses per cycle is measured over them)."},
    {"fatigue", "jump_breaks", "integer", "0", "bars", 0, 1e9, false, false, "", "At most this many bars may reach the end of their life within a jump (0: the jump stops short of the next bar's end; it then breaks while the cycles are resolved)."},
    {"fatigue", "jump_max", "float", "1e6", "cycles", 1, 1e12, false, false, "", "The largest jump."},
    {"fatigue", "jump_fraction", "float", "0.2", "", 0, 1, true, false, "", "In a jump no bar uses more than this fraction of a whole life, so that the rates it extrapolates change little within it (the bars' strain ranges grow as the damage ahead of a crack grows)."},
    {"fatigue", "box_min", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "With box_max: only bars that meet this box (a point of the bar inside it, faces included) have a fatigue life; the others follow the paper's law alone. Default: every bar. Confines fatigue to a crack's expected path, as cohesive fatigue models put their cohesive elements there: a thin box around a plane takes the bars that cross the plane (a weak interface, or a verification on a straight crack)."},
    {"fatigue", "box_max", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "See box_min."},
    {"fatigue", "length", "float", "lattice.L", "m", 0, kInf, true, false, "", "The bar length A is given for."},

    {"field", "type", "string", "required", "", -kInf, kInf, false, false, "\"linear\", \"table\", \"weibull\"", "A material property that varies per bar (`E = { type = ... }`), evaluated at the bar's centre; see docs/model.md for how e_p, e_r, K_r and Gf then follow."},
    {"field", "axis", "string", "\"z\"", "", -kInf, kInf, false, false, "\"x\", \"y\", \"z\"", "linear, table: the axis of the grading."},
    {"field", "values", "[2 floats]", "-", "", -kInf, kInf, false, false, "", "linear: the values at the two ends `at`."},
    {"field", "at", "[2 floats]", "the body's faces", "m", -kInf, kInf, false, false, "", "linear: the coordinates of the two ends (inside the body); constant beyond them."},
    {"field", "points", "[[coordinate, value], ...]", "-", "m, -", -kInf, kInf, false, false, "", "table: increasing coordinates inside the body; linear between points, constant beyond."},
    {"field", "mean", "float", "-", "", 0, kInf, true, false, "", "weibull: mean."},
    {"field", "cv", "float", "-", "", 0, kInf, true, false, "", "weibull: coefficient of variation (shape from CV^2 = G(1+2/g)/G(1+1/g)^2 - 1, scale from the mean)."},
    {"field", "seed", "integer", "1", "", 0, kInf, false, false, "", "weibull: seed; the field depends only on the seed and the bar's number (or position, when correlated)."},
    {"field", "correlation_length", "float", "0", "m", 0, kInf, false, false, "", "weibull: 0 draws each bar independently (correlation of the order of L); a length > 0 makes a Gaussian field with that correlation length, independent of L, mapped to the Weibull marginal."},
    {"field", "covariance", "string", "\"exponential\"", "", -kInf, kInf, false, false, "\"exponential\", \"squared_exponential\"", "weibull with correlation_length > 0: exp(-r / l) or exp(-(r / l)^2)."},

    {"geometry", "add", "table", "-", "", -kInf, kInf, false, false, "", "Add the modules whose centres lie inside this shape (see the shape keys below; boundaries included, to within 1e-9 L). When the first [[geometry]] adds, the body starts empty, else from the full box; the tables apply in order."},
    {"geometry", "remove", "table", "-", "", -kInf, kInf, false, false, "", "Remove the modules whose centres lie inside this shape: a hole, a notch with thickness. Pieces joined to the rest only by edges or corners are removed too, with a warning that counts them."},
    {"region", "shape", "table", "required", "", -kInf, kInf, false, false, "", "The region: the bars whose centres, and the modules (for rho) whose centres, lie inside this shape (boundaries included, to within 1e-9 L; see the shape keys below). A later region wins where regions overlap."},
    {"region", "E", "float or field", "-", "Pa", 1e-3, 1e15, false, false, "", "Young's modulus inside the region (a number, or a field as in [material])."},
    {"region", "Gf", "float or field", "-", "N/m", 0, kInf, true, false, "", "Fracture energy inside the region; only where [material] gives no e_r."},
    {"region", "e_p", "float or field", "-", "", 0, kInf, true, false, "", "Peak strain inside the region; only where [material] gives e_p (not R_f)."},
    {"region", "e_r", "float or field", "-", "", 0, kInf, true, false, "", "Rupture strain of the normal bars inside the region; only where [material] gives e_r."},
    {"region", "R_f", "float or field", "-", "m^-1/2", 0, kInf, true, false, "", "Failure factor inside the region; only where [material] gives R_f."},
    {"region", "rho", "float or field", "-", "kg/m^3", 1e-3, 1e6, false, false, "", "Density of the modules inside the region."},
    {"node_set", "name", "string", "required", "", -kInf, kInf, false, false, "", "Name used by conditions, loads and probes."},
    {"node_set", "face", "string", "-", "", -kInf, kInf, false, false, "\"x-\", \"x+\", \"y-\", \"y+\", \"z-\", \"z+\"", "The corner nodes on this face of the box."},
    {"node_set", "face_centres", "string", "-", "", -kInf, kInf, false, false, "\"x-\", \"x+\", \"y-\", \"y+\", \"z-\", \"z+\"", "The centre nodes of the layer of modules along this face."},
    {"node_set", "box_min", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "With box_max: every node inside this box (faces included)."},
    {"node_set", "box_max", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "See box_min."},
    {"node_set", "all", "bool", "false", "", -kInf, kInf, false, false, "", "Every node."},
    {"node_set", "shape", "table", "-", "", -kInf, kInf, false, false, "", "Every node inside this shape (`shape = { type = \"sphere\", centre = [...], radius = ... }`; boundaries included, to within 1e-9 L; see the shape keys below): a loading pad, a support, a gauge's region."},
    {"node_set", "surface", "bool", "false", "", -kInf, kInf, false, false, "", "With shape: only the corner nodes of the body's surface inside the shape (beside an absent module or the outside of the box; a body one module thick along an axis, a plate in plane strain, has no surface across it): a loading strip on a disc, the curved face of a cylinder."},

    {"shape", "type", "string", "required", "", -kInf, kInf, false, false, "\"box\", \"cylinder\", \"sphere\", \"half_space\", \"npy\", \"stl\"", "The kind of solid; only its own keys apply. \"npy\" and \"stl\" (in [[geometry]] only): the modules a NumPy file marks, or whose centres lie inside the closed surface of an STL file."},
    {"shape", "min", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "box: the corner with the smallest coordinates (before a turn)."},
    {"shape", "max", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "box: the opposite corner; at or above min on every axis."},
    {"shape", "axis", "string", "-", "", -kInf, kInf, false, false, "\"x\", \"y\", \"z\"", "box, with angle: the box is turned about the axis along this direction through its centre."},
    {"shape", "angle", "float", "-", "degrees", -360, 360, false, false, "", "box, with axis: the turn, right-handed about the axis."},
    {"shape", "start", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "cylinder: the centre of one end; the axis runs from start to end, in any direction."},
    {"shape", "end", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "cylinder: the centre of the other end (not start)."},
    {"shape", "radius", "float", "-", "m", 0, kInf, true, false, "", "cylinder, sphere: the radius."},
    {"shape", "centre", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "sphere: the centre."},
    {"shape", "point", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "half_space: a point on its boundary plane."},
    {"shape", "normal", "[3 floats]", "-", "", -kInf, kInf, false, false, "", "half_space: a vector out of the plane towards the inside (not zero): the points x with (x - point) . normal >= 0."},
    {"shape", "scale", "float", "1", "", 0, kInf, true, false, "", "stl: the factor from the file's units to metres (0.001 for millimetres)."},
    {"shape", "file", "string", "-", "", -kInf, kInf, false, false, "", "stl: an STL file (binary or ASCII) of a closed surface. npy: a NumPy .npy array of shape (nx, ny, nz), indexed [i, j, k] (C or Fortran order), of booleans, integers or floats: the modules where it is not zero; a relative path is from the case file's folder."},

    {"fixed", "set", "string", "required", "", -kInf, kInf, false, false, "", "Node set whose DOF are held at zero displacement."},
    {"fixed", "dofs", "string", "\"xyz\"", "", -kInf, kInf, false, false, "letters x, y, z", "Which DOF."},

    {"velocity", "set", "string", "required", "", -kInf, kInf, false, false, "", "Node set driven at an imposed velocity."},
    {"velocity", "dofs", "string", "\"xyz\"", "", -kInf, kInf, false, false, "letters x, y, z", "Which DOF are imposed (the others stay free). A DOF of a node may be imposed by one [[velocity]] table only, and not one a [[fixed]] table or plane strain holds: contradicting conditions are refused."},
    {"velocity", "value", "[3 floats]", "required", "m/s", -kInf, kInf, false, false, "", "Velocity, scaled by the time function."},
    {"velocity", "ramp", "float", "-", "s", 0, kInf, true, false, "", "Shortcut for function = [{type = \"ramp\", value = 1, duration = ramp}]."},
    {"velocity", "control", "table", "-", "", -kInf, kInf, false, false, "", "Loading controlled by a gauge probe (a constant CMOD rate): `control = { probe = \"cmod\", rate = 2.0e-3 }`. Before each step the set is driven at value * f, f = clamp((rate * t - probe) / (response_time * |value|), -1, 1): |value| is the fastest the controller may move the set, in value's direction (which must open the gauge when rate > 0); it backs off, and reverses, when the probe runs ahead (a snap-back). Replaces ramp and function. docs/model.md, \"Probe-controlled loading\"."},
    {"control", "probe", "string", "required", "", -kInf, kInf, false, false, "", "The [[probe]] that is controlled: a displacement, opening or strain probe."},
    {"control", "rate", "float", "required", "probe's unit / s", -kInf, kInf, false, false, "", "The probe's target is rate * t (m/s for a displacement or opening, 1/s for a strain); not 0."},
    {"control", "response_time", "float", "-", "s", 0, kInf, true, false, "", "The time in which the controller would cancel the probe's error if the probe moved as the set does: the velocity is (rate * t - probe) / response_time along value. Shorter follows the target more closely (the probe lags it by rate * response_time / G, G = probe motion per set motion) but drives the specimen's own vibration when it is below its lowest period. Default: 20 times the time a bar wave sqrt(E / rho) takes to cross the body's largest extent."},

    {"load", "name", "string", "required", "", -kInf, kInf, false, false, "", "Name (for probes)."},
    {"load", "set", "string", "required", "", -kInf, kInf, false, false, "", "Node set loaded."},
    {"load", "force", "[3 floats]", "-", "N", -kInf, kInf, false, false, "", "Force on each node of the set, scaled by the time function. Give one of force, traction, total and acceleration."},
    {"load", "traction", "[3 floats]", "-", "Pa", -kInf, kInf, false, false, "", "Force per area on the surface that the set covers, scaled by the time function: each node takes the area it stands for, a quarter of each module face around it whose four corners are in the set (a set by face: the box's face; by face_centres: a whole module face per centre; by shape with surface = true: the staircase surface of the body there, a loading strip on a disc, the curved face of a cylinder). The direction stays fixed (not a pressure that turns with the surface)."},
    {"load", "total", "[3 floats]", "-", "N", -kInf, kInf, false, false, "", "The whole force on the set, scaled by the time function, spread over the surface the set covers by the area each node stands for (as traction: traction = total / area): a load cell's force on a loading plate."},
    {"load", "acceleration", "[3 floats]", "-", "m/s^2", -kInf, kInf, false, false, "", "A body force per unit mass (gravity: [0, 0, -9.81]), scaled by the time function: each node of the set takes its lumped mass times it (a set by all: the whole body's weight, rho V g). A load constant in time costs nothing per step; one that varies costs a pass over its nodes each step."},

    {"platen", "name", "string", "required", "", -kInf, kInf, false, false, "", "Name (for probes and messages)."},
    {"platen", "shape", "string", "\"plane\"", "", -kInf, kInf, false, false, "\"plane\", \"cylinder\"", "A plane (a loading platen, a support, a wall that holds fragments) or a cylinder (a roller support, a loading roller, an indenter) that the body stays outside of."},
    {"platen", "point", "[3 floats]", "required", "m", -kInf, kInf, false, false, "", "Where it is at t = 0: plane, a point of its face; cylinder, a point of its axis."},
    {"platen", "normal", "[3 floats]", "-", "", -kInf, kInf, false, false, "", "plane: its normal (not zero; scaled to unit length), pointing from the platen towards the body: nodes with (x - point) . normal < 0 have passed it and are pushed back."},
    {"platen", "axis", "[3 floats]", "-", "", -kInf, kInf, false, false, "", "cylinder: the direction of its axis (not zero); it is infinitely long."},
    {"platen", "radius", "float", "-", "m", 0, kInf, true, false, "", "cylinder: its radius."},
    {"platen", "velocity", "[3 floats]", "[0, 0, 0]", "m/s", -kInf, kInf, false, false, "", "Its velocity, scaled by the time function (ramp or function, as a [[velocity]]'s); it moves without turning. [0, 0, 0]: it stays where it is."},
    {"platen", "ramp", "float", "-", "s", 0, kInf, true, false, "", "Shortcut for function = [{type = \"ramp\", value = 1, duration = ramp}]."},
    {"platen", "friction", "float", "0", "", 0, kInf, false, false, "", "Coulomb friction coefficient mu between the platen and the body: a touching node sticks while its tangential force is below mu times its normal force, and slides, dissipating, at that force (docs/model.md, \"Platens\"). 0: frictionless."},
    {"platen", "penalty", "float", "1", "", 0, kInf, true, false, "", "The penalty spring's stiffness: k = penalty E L on a node of a body face (E the body's largest, L the module size), in proportion to the node's lumped mass elsewhere (half on an edge, a quarter at a corner). The platen sinks into a face under a stress sigma by about sigma L / (penalty E); the stable step shrinks as sqrt(omega^2 + kappa) grows with kappa = 4 penalty E / (rho L^2)."},

    {"function", "type", "string", "required", "", -kInf, kInf, false, false, "\"constant\", \"ramp\", \"exp_rise\", \"growing_sine\", \"table\"", "One term of the time function of a velocity or load (`function = [{...}, ...]`, summed); without `function` the factor is 1. Every term is 0 before its t_start and from its t_end on; s = t - t_start is its own time."},
    {"function", "value", "float", "1", "", -kInf, kInf, false, false, "", "constant: value; ramp: value * min(s / duration, 1); exp_rise: value * (1 - exp(-s / tau))."},
    {"function", "duration", "float", "-", "s", 0, kInf, true, false, "", "ramp: time to reach the value."},
    {"function", "tau", "float", "-", "s", 0, kInf, true, false, "", "exp_rise, growing_sine: time constant."},
    {"function", "amplitude", "float", "-", "", -kInf, kInf, false, false, "", "growing_sine: final amplitude."},
    {"function", "frequency", "float", "-", "Hz", 0, kInf, true, false, "", "growing_sine: frequency."},
    {"function", "t_start", "float", "0", "s", 0, kInf, false, false, "", "Every term: the time it starts; its own time s = t - t_start runs from then (a ramp rises from then, a sine starts, a table's times count from then)."},
    {"function", "t_end", "float", "-", "s", 0, kInf, true, false, "", "Every term: from this time on the term is 0 (default: never). Must be after t_start."},
    {"function", "points", "[[2 floats], ...]", "-", "", -kInf, kInf, false, false, "", "table: the points [s, value], s increasing: the value is linear between them, the first value before the first point and the last after the last. For a load history: points = [[0, 0], [1e-3, 1], [2e-3, 1], [3e-3, 0]] loads, holds and unloads."},
    {"function", "n_cycles", "float", "0", "", 0, kInf, false, false, "", "growing_sine: cycles after which the amplitude stays constant."},

    {"precrack", "name", "string", "required", "", -kInf, kInf, false, false, "", "Name, for messages."},
    {"precrack", "origin", "[3 floats]", "required", "m", -kInf, kInf, false, false, "", "A corner of the rectangle."},
    {"precrack", "edge1", "[3 floats]", "required", "m", -kInf, kInf, false, false, "", "First edge vector from the origin."},
    {"precrack", "edge2", "[3 floats]", "required", "m", -kInf, kInf, false, false, "", "Second edge vector from the origin."},
    {"precrack", "nudge", "bool", "false", "", -kInf, kInf, false, false, "", "Move a rectangle lying on a plane of nodes by L/4 along its normal instead of refusing it."},

    {"time", "end", "float", "required", "s", 0, kInf, true, false, "", "Simulated time."},
    {"time", "rule", "string", "\"safety\"", "", -kInf, kInf, false, false, "\"safety\", \"dt\", \"paper\"", "Time step: a fraction of the stable step, a given dt, or the paper's courant L / c with c = sqrt(E / rho) the fastest bar wave speed, at the largest E and the smallest density of the body (0.6 L / c in the paper); a step above the stable limit is refused."},
    {"time", "courant", "float", "0.6", "", 0, 1, true, false, "", "Courant number of rule = \"paper\" (dt = courant L / c)."},
    {"time", "safety", "float", "0.9", "", 0, 1, true, false, "", "Fraction of the stable step (rule = \"safety\")."},
    {"time", "dt", "float", "-", "s", 0, 1e3, true, false, "", "Time step (rule = \"dt\")."},
    {"time", "stop_displacement", "float", "-", "m", 0, kInf, true, false, "", "End the run normally, before `end`, once a node moves farther than this from its place (a body that comes apart under loads); the outputs, analyses and plots are made as at `end`, and summary.json records `stopped_by`."},
    {"time", "damping", "float", "0", "1/s", 0, kInf, false, false, "", "Mass-proportional damping coefficient a (C = a M): the amplitude of every mode above a / (4 pi) Hz decays as exp(-a t / 2). Fatigue runs need it (see fatigue.gate)."},

    {"output", "energy_every", "integer", "0", "steps", 0, kInf, false, false, "", "Steps between rows of energy.csv and probes.csv; 0: about 500 rows."},
    {"output", "vtu_every", "integer", "0", "steps", 0, kInf, false, false, "", "Steps between lattice snapshots; 0: about 20."},
    {"output", "vtu", "bool", "true", "", -kInf, kInf, false, false, "", "Write lattice.pvd and its .vtu files."},
    {"output", "plots", "bool", "true", "", -kInf, kInf, false, false, "", "Make crack.png, energy.png, probes.png and response.png at the end (also: --no-plot)."},

    {"output", "checkpoint_every", "integer", "0", "steps", 0, kInf, false, false, "", "Steps between checkpoints in checkpoint/ (0: by wall time only). A stop by Ctrl-C or SIGTERM always leaves one; `ldem resume DIR` continues."},
    {"output", "checkpoint_seconds", "float", "600", "s", 0, kInf, false, false, "", "Wall-clock seconds between checkpoints (0: never by time)."},
    {"output", "vtu_arrays", "[strings]", "all", "", -kInf, kInf, false, false, "", "The arrays the snapshots hold besides the points and cells (and a shaped body's node and bar numbers): any of \"displacement\", \"velocity\", \"damage\", \"state\", \"axial_force\", \"strain\", the bar law's (the fatigue law's \"life\"), and where the material varies \"E\", \"Gf\", \"e_p\", \"e_r\"; and \"stress\", only when named: the stress at each node [Pa], a symmetric tensor (xx, yy, zz, xy, yz, xz), the mean of the stresses of the modules around the node, each its bars' virial over its volume; and \"node_strain\", only when named: the strain at each node, the same tensor's components, the mean of its modules' strains, each the volume mean of the symmetrised gradient of its corners' displacements (docs/model.md, \"Stress and strain at the nodes\"). vtu_arrays = [\"displacement\", \"damage\"] makes the tutorial plate's snapshots 1.5 times smaller (407 to 268 kB; the points and cells stay)."},
    {"output", "vtu_compression", "string", "\"none\"", "", -kInf, kInf, false, false, "\"none\", \"zlib\"", "\"zlib\": the snapshots' arrays zlib-compressed in blocks, as VTK and ParaView read them (vtkZLibDataCompressor): the tutorial plate's snapshots 2.8 times smaller (407 to 143 kB). Any number of processes write the same bytes."},
    {"output", "end_checkpoint", "bool", "true", "", -kInf, kInf, false, false, "", "At the end, a checkpoint in checkpoint/ of the run's last reported state, from which `ldem resume DIR --end T` runs it on to a later time T (the state takes about 200 bytes per module)."},

    {"analysis", "crack", "bool", "false", "", -kInf, kInf, false, false, "", "After the run, analyse the crack (as `ldem analyze crack DIR`): crack_tip.csv and `analysis.crack` in summary.json."},
    {"analysis", "min_branch_length", "float", "-", "m", 0, kInf, true, false, "", "Default 6 L. A branch must run at least this far beyond its bifurcation (shorter side cracks are not branches)."},
    {"analysis", "branch_fit_length", "float", "-", "m", 0, kInf, true, false, "", "Default 10 L. Branch angles: a straight line fitted over this length of each branch from its bifurcation."},
    {"analysis", "speed_window", "float", "-", "s", 0, kInf, true, false, "", "Default 4 L / c_R (c_R: Rayleigh speed of the mean E). Bars broken more than this before the crack reaches them broke on their own and are not part of it; the tip is sampled every quarter of this time."},
    {"analysis", "speed_fit_length", "float", "-", "m", 0, kInf, true, false, "", "Default 10 L. Tip speed: the slope of a least-squares line through the tip's distance along the crack against time, over a window in which the tip advances at least this much."},
    {"analysis", "zone_flag_length", "float", "-", "m", 0, kInf, true, false, "", "Default 3 L. A tip speed whose fit window holds a sample where the softened zone runs farther than this ahead of the crack is flagged (the crack then runs through a ligament that softened before it got there)."},
    {"analysis", "fatigue", "bool", "false", "", -kInf, kInf, false, false, "", "After the run, measure subcritical crack growth (as `ldem analyze fatigue DIR`): fatigue.csv, fatigue_front.csv, fatigue_columns.csv and `analysis.fatigue` in summary.json."},
    {"analysis", "fatigue_load", "string", "-", "", -kInf, kInf, false, false, "", "Default: the first load with a \"growing_sine\" term. The load whose total force over the body's section normal to it is the remote stress, and whose sine counts the cycles (N = 0 when its amplitude becomes constant)."},
    {"analysis", "fatigue_points", "integer", "10", "", 3, 10000, false, false, "", "Representative points of a(N), evenly spaced in N over the subcritical window at constant amplitude; da/dN between neighbours."},
    {"analysis", "fatigue_rate", "string", "\"points\"", "", -kInf, kInf, false, false, "\"points\", \"secant\"", "How da/dN is taken over the window: between fatigue_points representative points evenly spaced in N (as the paper), or between consecutive steps of the damage front (the secant method of ASTM E647), which follows a rate that changes by orders of magnitude over the growth."},
    {"analysis", "fatigue_fit_after", "float", "0", "m", 0, kInf, false, false, "", "Intervals whose crack tip lies less than this beyond the pre-crack's tip are listed in fatigue.csv but left out of the Paris fit: the growth away from a cut notch, before the crack has a tip of its own (as ASTM E647 leaves out the growth from a machined notch)."},
    {"analysis", "fatigue_fit_elastic", "bool", "false", "", -kInf, kInf, false, false, "", "Leave out of the Paris fit the intervals that end after the first bar within fatigue_band of the crack softens: the fit then covers small-scale yielding, the bulk still elastic, as linear elastic fracture mechanics assumes (for the fatigue law; the paper's law grows only by softening)."},
    {"analysis", "fatigue_window", "string", "\"constant\"", "", -kInf, kInf, false, false, "\"constant\", \"cycles\"", "Where the representative points lie: the cycles at constant amplitude (N >= 0, as the paper), or every cycle from the first (growth under the rising amplitude too, each interval with its own cycle's stress range)."},
    {"analysis", "fatigue_band", "float", "-", "m", 0, kInf, true, false, "", "Default a quarter of the body across the crack. Only bars centred within this distance of the pre-crack's plane make the damage front."},
    {"analysis", "fatigue_unstable_advance", "float", "-", "m", 0, kInf, true, false, "", "Default a tenth of the width b. A front advance of at least this much within one load period marks the onset of unstable failure."},
    {"analysis", "fatigue_width", "float", "-", "m", 0, kInf, true, false, "", "Default the body's size along the crack. Width b of the single-edge-cracked plate in Delta K = Delta sigma sqrt(pi a) F(a/b)."},

    {"probe", "name", "string", "required", "", -kInf, kInf, false, false, "", "Column name in probes.csv."},
    {"probe", "kind", "string", "required", "", -kInf, kInf, false, false, "\"bar_force\", \"reaction\", \"load\", \"displacement\", \"opening\", \"strain\", \"platen\", \"platen_displacement\"", "What to record."},
    {"probe", "at", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "bar_force: axial force [N] of the bar whose centre is nearest to this point. displacement: the displacement [m] of the body's node nearest to this point (an LVDT)."},
    {"probe", "set", "string", "-", "", -kInf, kInf, false, false, "", "reaction: the static support force on the set [N]: minus the sum of the bar forces and loads on its nodes, the whole support force on held DOF; on imposed-velocity DOF without the driven nodes' inertia and damping (docs/model.md, 6). displacement (instead of at): the mean displacement [m] of the set's nodes."},
    {"probe", "component", "string", "\"z\"", "", -kInf, kInf, false, false, "\"x\", \"y\", \"z\"", "reaction, displacement, opening, platen, platen_displacement: component."},
    {"probe", "platen", "string", "-", "", -kInf, kInf, false, false, "", "platen: name of the [[platen]] whose force on the body [N] is recorded (the sum of its contact forces, normal and friction, along the component). platen_displacement: the platen whose displacement from its place at t = 0 [m] is recorded."},
    {"probe", "from", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "opening, strain: the gauge's first end, the body's node nearest to this point (or give from_set)."},
    {"probe", "from_set", "string", "-", "", -kInf, kInf, false, false, "", "opening, strain: the gauge's first end, the mean over this node set's nodes (their mean position for the gauge length)."},
    {"probe", "to", "[3 floats]", "-", "m", -kInf, kInf, false, false, "", "opening, strain: the gauge's second end, the node nearest to this point (or give to_set). opening: u(to) - u(from) along the component [m] (a CMOD or crack-opening gauge); strain: (u(to) - u(from)) . d / l, d the unit vector from the first end's position to the second's and l their distance (an extensometer)."},
    {"probe", "to_set", "string", "-", "", -kInf, kInf, false, false, "", "opening, strain: the gauge's second end, the mean over this node set's nodes."},
    {"probe", "load", "string", "-", "", -kInf, kInf, false, false, "", "load: name of the load whose total force [N] (component along its direction) is recorded."},
  };
  return keys;
}
// clang-format on

std::string case_format_markdown() {
  std::string md =
      "# Case file format\n\n"
      "A case is a TOML file. This page is generated from the declarations in\n"
      "`src/io/case_keys.cpp` (`ldem case-format` prints it). Unknown keys are errors, and so\n"
      "are keys that do not apply to their table's kind (the meanings below say which: `points`\n"
      "on a `ramp` term, `courant` without `rule = \"paper\"`, `at` on a reaction probe).\n"
      "Tables: `[case]`, `[lattice]`, `[material]`, `[fatigue]` (with `law =\n"
      "\"bilinear_fatigue\"` only), `[time]`, `[output]`, `[analysis]`; arrays\n"
      "of tables:\n"
      "`[[geometry]]`, `[[region]]`, `[[node_set]]`, `[[fixed]]`, `[[velocity]]`, `[[load]]`,\n"
      "`[[platen]]`, `[[precrack]]`, `[[probe]]`;\n"
      "a velocity, load or platen may carry `function = [{ type = ..., ... }, ...]`, whose terms are\n"
      "summed, and a velocity `control = { probe = ..., rate = ... }` instead; a node set may\n"
      "be a shape, `shape = { type = ..., ... }`. Coordinates are in\n"
      "metres from the box's corner at the origin; the box spans\n"
      "`[0, nx L] x [0, ny L] x [0, nz L]`.\n";
  const char* last = "";
  for (const KeyDecl& k : case_keys()) {
    if (std::string(k.table) != last) {
      const std::string t = k.table;
      const bool array = t == "geometry" || t == "region" || t == "node_set" || t == "fixed" ||
                         t == "velocity" || t == "load" || t == "platen" || t == "precrack" ||
                         t == "probe";
      md += fmt::format("\n## {}\n\n| key | type | default | unit | allowed | meaning |\n"
                        "|---|---|---|---|---|---|\n",
                        t == "field"      ? "material fields (`E = { type = ... }`)"
                        : t == "shape"    ? "shapes (`shape = { type = ... }`)"
                        : t == "function" ? "function terms (`function = [{...}]`)"
                        : t == "control"  ? "velocity control (`control = {...}`)"
                        : array           ? "[[" + t + "]]"
                                          : "[" + t + "]");
      last = k.table;
    }
    md += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", k.key, k.type, k.fallback, k.unit,
                      k.range_text(), k.help);
  }
  return md;
}

} // namespace ldem
