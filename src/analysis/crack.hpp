// Crack analysis of a run: the crack path from the broken bars, the crack tip and its speed
// against time, and the detection of branching (docs/model.md, "Crack analysis").
#pragma once

#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace ldem {

// A broken bar as the analysis sees it: when it broke and where its centre lies in the
// analysis plane (a: along the pre-crack, n: across it, both in m).
struct CrackPoint {
  double t, a, n;
};

struct CrackGeometry {
  double L = 0.0;                              // module edge [m]
  double a_lo = 0, a_hi = 0, n_lo = 0, n_hi = 0; // the body in the analysis plane [m]
  double mouth_a = 0, tip_a = 0, line_n = 0;   // the pre-crack: from mouth to tip, at n = line_n
};

struct CrackOptions {
  double min_branch_length = 0.0; // a branch must run this far beyond its bifurcation [m]
  double fit_length = 0.0;        // branch angles: a line fit over this length of a branch [m]
  // Bars broken more than this before the crack reaches them broke on their own; the tip is
  // sampled every quarter of it [s].
  double speed_window = 0.0;
  double speed_fit_length = 0.0; // tip speed: a least-squares line over this much advance [m]
  // Samples where the softened zone runs farther ahead of the tip than this are flagged [m].
  double zone_flag_length = 0.0;
};

// The tip of one part of the crack at one time: the trunk (branch 0: the crack up to its first
// bifurcation, or the whole crack if it does not branch) or branch k of the first bifurcation.
struct TipSample {
  double t = 0.0;
  int branch = 0;
  double a = 0.0, n = 0.0;
  double length = 0.0;   // pre-crack + that part's farthest extent along the crack [m]
  double speed = 0.0;    // least-squares slope of the length over >= speed_fit_length [m/s]
  double speed_se = 0.0; // its standard error (NaN with fewer than 3 samples) [m/s]
  double softening_length = 0.0; // pre-crack + the softened zone's extent, whole crack [m]
  double softened_ahead = 0.0;   // how far the softened zone runs ahead of the whole crack [m]
  // The speed's window holds a sample whose softened_ahead > zone_flag_length.
  bool flagged = false;
  bool jump = false; // the speed's window holds a step of > 2 L between samples (coalescence)
};

struct BranchInfo {
  int level = 1;          // 1: a branch of the first bifurcation; 2: of a secondary one
  double angle_deg = 0.0; // to the pre-crack direction, positive towards +n
  double length = 0.0;    // extent along its path beyond its bifurcation [m]
  bool opens = false;     // reaches the body's border: with the rest of the crack it cuts the body
  double end_a = 0.0, end_n = 0.0; // its farthest point
  // Level 1: median tip speed while it grows, largest tip speed (NaN: none measured) [m/s].
  double median_speed = std::numeric_limits<double>::quiet_NaN();
  double max_speed = std::numeric_limits<double>::quiet_NaN();
};

struct CrackAnalysis {
  std::optional<double> branching_length; // bifurcation point, from the mouth along a [m]
  double branch_a = 0.0, branch_n = 0.0;  // the bifurcation point [m]
  std::vector<BranchInfo> branches;       // the first bifurcation's, then secondary ones
  bool secondary_branching = false;
  // Speeds over windows without a jump (the crack joining bars broken ahead of it).
  double max_speed = 0.0;    // largest tip speed of the trunk and the branches [m/s]
  double max_speed_se = 0.0; // its standard error [m/s]
  // The largest over windows where the softened zone stays short (NaN: none) [m/s].
  double max_unflagged_speed = std::numeric_limits<double>::quiet_NaN();
  int jumps = 0;                    // steps of more than 2 L between two samples of a tip
  // Median tip speed while the crack grows, and the trunk's alone (NaN: none measured) [m/s].
  double median_speed = std::numeric_limits<double>::quiet_NaN();
  double trunk_median_speed = std::numeric_limits<double>::quiet_NaN();
  // Largest trunk speed until its tip reaches the bifurcation (NaN: none measured) [m/s].
  double speed_before_branching = std::numeric_limits<double>::quiet_NaN();
  double flagged_time = 0.0; // time during which the softened zone ran far ahead [s]
  double final_length = 0.0; // pre-crack + the farthest extent along the crack's path [m]
  double final_softening_length = 0.0; // the same for the softened zone [m]
  std::vector<TipSample> tip;    // by time, then branch
  std::size_t bars_in_crack = 0; // broken bars connected to the pre-crack
  std::size_t bars_elsewhere = 0; // broken bars that are not (border damage, isolated bars)
};

// The analysis itself, on broken-bar centres (and the first-softening points of bars, for the
// softened zone) already projected onto the analysis plane.
CrackAnalysis analyze_crack(const std::vector<CrackPoint>& broken, const CrackGeometry& g,
                            const CrackOptions& o,
                            const std::vector<CrackPoint>& softening = {});

// Rayleigh wave speed of an isotropic solid [m/s] (root of the Rayleigh equation).
double rayleigh_speed(double E, double nu, double rho);

// A few lines for the terminal: branching length and angles, speeds, bars counted.
std::string crack_report(const CrackAnalysis& r);

// `ldem analyze crack DIR`: reads DIR/case.resolved.toml and DIR/events.csv, writes
// DIR/crack_tip.csv and `analysis.crack` in DIR/summary.json. Returns the analysis.
CrackAnalysis analyze_crack_dir(const std::string& dir);

} // namespace ldem
