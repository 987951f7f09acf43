// Subcritical (fatigue) crack growth measured the way the LDEM paper proposes: the time each
// bar first reaches e_p and reaches e_r against the position of its centre along the crack,
// the front of first-damaged bars as a(t), cycles N, da/dN, Delta K of a single-edge-cracked
// plate and Paris' law fitted in log-log (docs/model.md, "Fatigue analysis").
#pragma once

#include "analysis/run_data.hpp"

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

// Tada's closed form of the geometry factor of a single-edge-cracked plate in tension,
// K = sigma sqrt(pi a) F(a/b) (Tada, Paris & Irwin, The Stress Analysis of Cracks Handbook):
// F = sqrt(2/(pi s) tan(pi s/2)) (0.752 + 2.02 s + 0.37 (1 - sin(pi s/2))^3) / cos(pi s/2).
// Accepted for 0 < s <= kTadaMaxRatio; anything else throws InputError.
inline constexpr double kTadaMaxRatio = 0.6;
double tada_edge_crack_factor(double a_over_b);

// A least-squares line through (log10 Delta K, log10 da/dN): da/dN = C Delta K^m.
struct ParisFit {
  double C = 0.0, m = 0.0;
  double log10_C = 0.0;
  double r2 = 0.0;                  // coefficient of determination in log-log
  double m_low = 0.0, m_high = 0.0; // two-sided confidence interval of m (Student t, n - 2)
  double confidence = 0.95;
  std::size_t points = 0;
};
// Needs at least 3 points with positive values and distinct Delta K; throws InputError
// otherwise. With exactly 3 points the interval is wide but defined.
ParisFit fit_paris(const std::vector<double>& delta_K, const std::vector<double>& da_dN,
                   double confidence = 0.95);

// A bar's event as the fatigue analysis sees it: the time, and its centre along the crack
// (x, from the border the pre-crack starts at) and across it (n).
struct BarEvent {
  double t, x, n;
};

// The front of damage: for every column of modules (width L along x) at or beyond the
// pre-crack tip, the earliest event among the bars of that column within `band` of the crack
// plane; the front a(t) is the far edge of the last column of the unbroken run of reached
// columns that starts at the tip's column. Returned as the times the front advances.
struct FrontStep {
  double t; // when the front reached...
  double a; // ...this position [m]
};
struct FrontOptions {
  double L = 0.0;     // module edge [m]
  double tip = 0.0;   // pre-crack tip along x [m]
  double plane = 0.0; // the crack plane's position across x [m]
  double band = 0.0;  // half-width of the band around the plane searched for events [m]
  double x_end = 0.0; // the far border of the body along x [m]
};
// Earliest event per column (NaN where none), columns counted from x = 0.
std::vector<double> column_first_times(const std::vector<BarEvent>& events, const FrontOptions& o);
std::vector<FrontStep> damage_front(const std::vector<BarEvent>& events, const FrontOptions& o);
// The front at time t: the last step at or before t (the tip before the first step).
double front_at(const std::vector<FrontStep>& front, double tip, double t);

// The events that make the damage front: the bars' first softening and their ruptures. A bar
// of the paper's law softens before it breaks, so its rupture never comes first; a bar of the
// fatigue law may break from the intact state when its life runs out, and that is its first
// damage.
std::vector<BarEvent> first_damage(const std::vector<BarEvent>& softening,
                                   const std::vector<BarEvent>& broken);

// The loading of the fatigue analysis: the remote stress sigma(t) of one load and the start
// and frequency of its cycles.
// The remote stress [Pa] of a resolved [[load]] of the run at time factor 1: its traction, or
// its total force (force per node times nodes) over the body's section normal to the force.
double load_remote_stress(const RunGeometry& rg, const toml::table& load);

struct CyclicLoad {
  double frequency = 0.0;       // Hz
  double t_cycles = 0.0;        // when the oscillation starts [s]
  double t_constant = 0.0;      // when the amplitude becomes constant: N = 0 [s]
  std::vector<double> t, sigma; // remote stress sampled finely enough to find each cycle's range
  // Cycle jumping: the times of energy.csv's rows and the cycles jumped before each row's state
  // (a jump follows its row); empty without jumps.
  std::vector<double> row_t, jumped;
  // Stress range max - min over the load period centred on t [Pa].
  double range_at(double time) const;
  // The cycles since the amplitude became constant at time t: (t - t_constant) f, plus the
  // cycles jumped before t (those of the first row at or after t).
  double cycles_at(double time) const;
};

struct FatigueOptions {
  double b = 0.0;                // the plate's width along the crack [m]
  std::size_t points = 10;       // representative points of a(N) over the subcritical window
  double unstable_advance = 0.0; // a front advance within one period that means unstable [m]
  double confidence = 0.95;
  // The window of representative points: false, the cycles at constant amplitude (N >= 0, as
  // the paper); true, every cycle from the first (growth under the rising amplitude too, each
  // interval with its own cycle's stress range).
  bool from_first_cycle = false;
  // How da/dN is taken over the window: false, between `points` representative points evenly
  // spaced in N (the paper); true, between consecutive steps of the front (the secant method of
  // ASTM E647 on the (N, a) record), which follows a rate that changes by orders of magnitude;
  // the interval's a is then the tip's mean position, the fronts' mean less one module (the
  // tip lies in the column the front has just reached).
  bool secant = false;
  // Intervals whose tip lies less than this beyond the pre-crack's tip are listed but left out
  // of the fit [m]: the growth away from a cut notch, before the crack has its own tip (as
  // ASTM E647 leaves out the growth from a machined notch).
  double fit_after = 0.0;
  // Leave out of the fit the intervals that end after the first bar within the band softens,
  // once the window has started: the fit then covers small-scale yielding, the bulk still
  // elastic (the fatigue law's cracks; the paper's law grows only by softening).
  bool fit_elastic = false;
};

struct FatigueRow {
  double N, a, da_dN, delta_K; // midpoint of an interval between representative points
  bool in_fit;                 // positive da/dN and a/b within Tada's range
};

struct FatigueAnalysis {
  std::optional<double> first_softening_t;     // in the window, with FatigueOptions::fit_elastic
  std::vector<FrontStep> front, rupture_front; // e_p and e_r fronts
  double t_end = 0.0;                          // tmax: the run's last time [s]
  std::optional<double> subcritical_start_t;   // front leaves the pre-crack's process zone
  std::optional<double> unstable_t;            // onset of unstable failure
  std::optional<double> cycles_to_failure;     // N at unstable_t
  double a_at_constant = 0.0;                  // front when N = 0 [m]
  std::vector<double> rep_N, rep_a;            // representative points of a(N)
  std::vector<FatigueRow> rows;
  std::optional<ParisFit> paris;
  std::string note; // why no fit, if none
};

FatigueAnalysis analyze_fatigue(const std::vector<BarEvent>& softening,
                                const std::vector<BarEvent>& broken, const FrontOptions& fo,
                                const CyclicLoad& load, const FatigueOptions& o, double t_end);

std::string fatigue_report(const FatigueAnalysis& r);

// `ldem analyze fatigue DIR`: reads DIR/case.resolved.toml and DIR/events.csv, writes
// DIR/fatigue.csv, DIR/fatigue_front.csv, DIR/fatigue_columns.csv and `analysis.fatigue` in
// DIR/summary.json. `window` ("constant" or "cycles") overrides the case's fatigue_window,
// `rate` ("points" or "secant") its fatigue_rate.
FatigueAnalysis analyze_fatigue_dir(const std::string& dir, const std::string& window = "",
                                    const std::string& rate = "");

} // namespace ldem
