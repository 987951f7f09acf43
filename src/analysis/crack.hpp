// Crack analysis of a run: the crack path from the broken bars, the crack tip and its speed
// against time, and the detection of branching (docs/model.md, "Crack analysis").
#pragma once

#include <cstddef>
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
  double speed_window = 0.0;      // crack speed: centred difference over +- this time [s]
};

struct TipSample {
  double t, a, n;
  double length; // pre-crack + the crack's extent along its path [m]
  double speed;  // m/s
};

struct BranchInfo {
  int level = 1;          // 1: a branch of the first bifurcation; 2: of a secondary one
  double angle_deg = 0.0; // to the pre-crack direction, positive towards +n
  double length = 0.0;    // extent along its path beyond its bifurcation [m]
  bool opens = false;     // reaches the body's border: with the rest of the crack it cuts the body
  double end_a = 0.0, end_n = 0.0; // its farthest point
};

struct CrackAnalysis {
  std::optional<double> branching_length; // bifurcation point, from the mouth along a [m]
  double branch_a = 0.0, branch_n = 0.0;  // the bifurcation point [m]
  std::vector<BranchInfo> branches;       // the first bifurcation's, then secondary ones
  bool secondary_branching = false;
  double max_speed = 0.0;   // m/s
  double speed_before_branching = 0.0; // largest speed until the tip passes the bifurcation
  double final_length = 0.0; // pre-crack + the farthest extent along the crack's path [m]
  std::vector<TipSample> tip;
  std::size_t bars_in_crack = 0; // broken bars connected to the pre-crack
  std::size_t bars_elsewhere = 0; // broken bars that are not (border damage, isolated bars)
};

// The analysis itself, on broken-bar centres already projected onto the analysis plane.
CrackAnalysis analyze_crack(const std::vector<CrackPoint>& broken, const CrackGeometry& g,
                            const CrackOptions& o);

// Rayleigh wave speed of an isotropic solid [m/s] (root of the Rayleigh equation).
double rayleigh_speed(double E, double nu, double rho);

// A few lines for the terminal: branching length and angles, speeds, bars counted.
std::string crack_report(const CrackAnalysis& r);

// `ldem analyze crack DIR`: reads DIR/case.resolved.toml and DIR/events.csv, writes
// DIR/crack_tip.csv and `analysis.crack` in DIR/summary.json. Returns the analysis.
CrackAnalysis analyze_crack_dir(const std::string& dir);

} // namespace ldem
