// `ldem check`, `ldem run`, `ldem resume`, `ldem plot` and `ldem modes`: from a case file to an
// output folder (or, for check and modes, to a report on the terminal). A case is built in
// case_build.cpp, the commands are in commands.cpp, and the time-step loop of run and resume
// in run_loop.cpp, stepping a RunBody (run_body.hpp).
#pragma once

#include "io/case_spec.hpp"
#include "solver/simulation.hpp"

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

// A case turned into a ready Simulation, with what the outputs need to know about it.
struct BuiltCase {
  std::string path; // the case file
  CaseSpec spec;
  std::unique_ptr<Simulation> sim;
  std::vector<NodeSet> sets;
  std::vector<index_t> precracked;
  // Bars without a fatigue life (not meeting [fatigue] box_min/box_max), in the body's
  // numbering.
  std::vector<index_t> lifeless;
  std::vector<CutResult> cuts;
  std::vector<index_t> probe_bars; // per probe: the bar of a bar_force probe
  // Per probe of kind displacement, opening or strain (empty for the others): the value is
  // scale * (mean over `to` of term(u) - mean over `from` of term(u)), term(u) the component
  // `component` of u or, for component < 0, u . dir (probe_term). A displacement probe has no
  // `from`.
  struct Gauge {
    std::vector<index_t> from, to;
    int component = -1;
    Vec3 dir;
    double scale = 1.0;
  };
  std::vector<Gauge> probe_gauges;
  // The controlled velocities (velocity.control), in the order of ImposedVelocity::control:
  // the gauge probe's index in probes, its target's rate, the response time [s] and the set's
  // top speed |value| [m/s]. RunBody::step sets their factors before each step.
  struct Control {
    std::size_t probe = 0;
    double rate = 0.0, response_time = 0.0, speed = 0.0;
  };
  std::vector<Control> controls;
  std::vector<std::string> warnings;
  // [[geometry]]: modules removed as hinged pieces, and the pieces of the body.
  std::uint64_t hinged_modules = 0, pieces = 1;
  // What the simulation was built from, for runs that build it again in subdomains: the body's
  // lattice, its conditions and the solver options (the material fields are evaluated again
  // per subdomain, from spec).
  std::optional<Lattice> lattice;
  Conditions conditions;
  SolverOptions options;
  // Cycle jumping ([fatigue] jump = true): the cyclic load's frequency [Hz] and the time from
  // which its amplitude is constant (its growing_sine's start plus n_cycles periods) [s].
  struct LoadCycle {
    double frequency = 0.0, t_constant = 0.0;
  };
  std::optional<LoadCycle> cycle;
};

// The per-bar and per-module properties of a case's material: its fields, then each
// [[region]] over the bars and modules whose centres lie inside it; for the bars `bars` and the
// modules `modules` of the body `whole` (their body numbers, in order; null: all of them).
// A property neither a field nor a region gives stays empty (uniform).
BarFields case_fields(const CaseSpec& s, const Lattice& whole, const std::vector<index_t>* bars,
                      const std::vector<index_t>* modules);

// The node set named `name` among `sets`; throws InputError when there is none.
const NodeSet& set_named(const std::vector<NodeSet>& sets, const std::string& name);
// A gauge probe's term of one node of displacement u (BuiltCase::Gauge).
inline double probe_term(const BuiltCase::Gauge& g, Vec3 u) {
  if (g.component >= 0)
    return g.component == 0 ? u.x : g.component == 1 ? u.y : u.z;
  return u.x * g.dir.x + u.y * g.dir.y + u.z * g.dir.z;
}
// The gauge's value from the sums of its terms over `from` and over `to`, each in its order.
inline double gauge_value(const BuiltCase::Gauge& g, double sum_from, double sum_to) {
  const double a = g.from.empty() ? 0.0 : sum_from / static_cast<double>(g.from.size());
  return g.scale * (sum_to / static_cast<double>(g.to.size()) - a);
}

// Throws InputError unless the case's time.end holds at least one step of dt.
void check_end_time(const BuiltCase& c, double dt);
// A law with a fatigue life: the bars `bars` (the simulation's numbering) get an endless life,
// so that cycles never break them. Nothing for other laws.
void remove_fatigue_life(Simulation& sim, const std::vector<index_t>& bars);

// The size of the whole force of load `i` of the case at time t [N]: its force per node times
// the node count, its traction times the area it acts on (a total: the total), or its
// acceleration times the mass of its nodes.
double load_total_force(const BuiltCase& c, std::size_t i, double t);

// An error found after the case was read, as "path:line: message" when the message begins
// with a key the case has ("time.damping: ..."), else "path: message".
std::string located(const CaseSpec& s, const std::string& path, const std::string& message);

// Builds everything a run needs; bad input throws InputError naming the case file. `adjust`,
// if given, changes the case after it is read (ensemble perturbations). Without
// `with_simulation`, sim stays empty (the processes of a distributed run other than the first
// build only their subdomain). With `text`, the case is that text and `path` only names it (in
// messages, and its folder is where relative file names start).
BuiltCase build_case(const std::string& path,
                     const std::function<void(CaseSpec&)>& adjust = nullptr,
                     bool with_simulation = true, const std::string* text = nullptr);

struct RunOptions {
  std::string out_dir;
  int threads = 0;
  bool force = false;
  bool plots = true;
  long long checkpoint_every = -1;  // steps; < 0: the case's output.checkpoint_every
  double checkpoint_seconds = -1.0; // < 0: the case's output.checkpoint_seconds
  // Under mpirun: the processes along y and z (0 0: the grid that cuts the least).
  int grid_y = 0, grid_z = 0;
  std::function<void(CaseSpec&)> adjust; // applied to the case after reading (ensembles)
  // A case given as text (the Python module's cases from strings and dicts): the run is built
  // from it, `path` naming it in messages, and writes it as case.toml in the output folder,
  // the file that the run's summary names and a resume reads.
  std::optional<std::string> case_text;
};

int check_command(const std::string& path);
// The set-up's progress (SolverOptions::setup_progress) on the first process's standard error,
// once it has taken 2 s: a large body's set-up says what it is doing.
void setup_progress_line(const std::string& phase, double seconds);
int run_command(const std::string& path, const RunOptions& options);
// Continues the run in `out_dir` from its checkpoint: an interrupted one, or with `end` (a time
// after the checkpoint's) any run, a finished one from its end checkpoint included, to that end.
// With `new_case`, the run goes on under that case file instead of its own (the same body,
// material, pre-cracks and probes; other supports, loads, node sets and end time), which
// replaces case.resolved.toml. Under mpirun, grid_y x grid_z processes (0 0: the grid that
// cuts the least).
int resume_command(const std::string& out_dir, int threads, bool plots, int grid_y = 0,
                   int grid_z = 0, std::optional<double> end = std::nullopt,
                   const std::string& new_case = "");
// The pictures of an output folder (tools/plot/ldem_plot.py); `view` ("xz", ...) and `cut`
// ("y=0.015") choose crack.png's projection or slice (empty: the default for the body).
// 0: done; 1: the script failed (no matplotlib, or its own message); 2: not an output folder,
// or a bad view or slice (the script says which).
int plot_command(const std::string& dir, const std::string& view = "", const std::string& cut = "");
// Why the plotting script failed, for a warning: matplotlib missing (with the package to
// install), or the script's own message.
std::string plot_failure_reason();
// Prints the `count` lowest eigenfrequencies of the case's lattice (solver/modes.hpp) as a table,
// with the time step and any periodic load frequency compared to the lowest. No files.
int modes_command(const std::string& path, int count, int threads);

// The numbers of a built body that the resolved case reports.
struct BodyNumbers {
  MaterialRanges ranges{};
  DuctilitySummary ductility{};
  StableStep stable{};
  double dt = 0.0;
  // The simulation's memory per module (distributed: the busiest process's per module it
  // owns), for summary.json.
  double bytes_per_module = 0.0;
  bool per_bar = false; // some material property varies from bar to bar
};
BodyNumbers body_numbers(const Simulation& sim);

// The warning a step above the proven stable bound (StableStep::dt_bound) deserves, with how
// far above it is, or none.
std::optional<std::string> time_step_warning(const BodyNumbers& n);

// The resolved case (every default and derived value), as TOML.
std::string resolved_case_toml(const BuiltCase& c, const BodyNumbers& n);

} // namespace ldem
