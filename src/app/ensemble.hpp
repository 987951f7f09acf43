// `ldem ensemble`: each case run several times under admissible perturbations, with a table
// of the crack analysis and energies of every run, and their median and range per case.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace ldem {

struct EnsembleOptions {
  std::vector<std::string> cases;
  int runs = 8;
  std::string out_dir = "results/ensemble";
  int threads = 0; // per run (0: the runs share the cores, util/core_share.hpp)
  int jobs = 0;    // runs at once (0: the cores, or the cores over `threads`)
  bool force = false;
  bool plots = true;
};

// The perturbation of run i of n: the paper's step rule with a Courant number from 0.6 (run 0)
// down to 0.5 (run n-1); the imposed velocities scaled by 1 + eps (eps = 0 for run 0, then
// -1e-12 and +1e-12 alternately); the pre-crack on the side of its node plane where the case
// puts it (runs 0, 1, 4, 5, ...) or mirrored to the other side (runs 2, 3, 6, 7, ...).
struct Perturbation {
  double courant = 0.6;
  double velocity_eps = 0.0;
  bool mirror_precrack = false;
};
Perturbation perturbation(int i, int n);
struct CaseSpec;
// The change run i of n makes to its case (the perturbation, the crack analysis on, snapshots
// kept by run 0 only): `ldem run --ensemble-member I N`, which the ensemble starts.
std::function<void(CaseSpec&)> ensemble_adjust(int i, int n);

int ensemble_command(const EnsembleOptions& o);

} // namespace ldem
