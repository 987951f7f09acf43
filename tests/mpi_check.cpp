// The subdomain scenario across real MPI ranks (mpirun -np P), on every grid of P processes
// that fits the body: every rank steps its subdomain and exchanges its ghost nodes through
// MPI; rank 0 also steps the whole body and compares every owned node's displacement, every
// owned bar's history and the energies summed over the ranks, bit for bit; and the body's
// stable step computed by the ranks together against the whole body's.
// Exit code 0 when all agree, 1 at the first difference.
#include "parallel/comm.hpp"
#include "subdomain_scenario.hpp"

#include <cstdio>
#include <omp.h>

using namespace ldem;
using ldem::testing::SubdomainScenario;

namespace {

// 0 when every rank's subdomain agrees with the whole body, 1 otherwise (on every rank).
int check(bool loaded, ProcessGrid grid) {
  const int rank = process_rank();
  Simulation whole = SubdomainScenario::whole(loaded);
  const Lattice& lat = whole.lattice();
  SubdomainRun run = SubdomainScenario::subdomain(grid, rank, whole.dt(), loaded);
  // The body's stable step from the subdomains: the Lanczos iteration's dot products and the
  // Gershgorin bound's maximum over the processes give one process's numbers, bit for bit.
  const StableStep stable = distributed_stable_step(run, lat);
  const StableStep& expected = whole.stable_step();
  if (stable.omega_max != expected.omega_max || stable.omega_bound != expected.omega_bound ||
      stable.iterations != expected.iterations) {
    std::printf("mpi_check: %d x %d ranks: stable step omega_max %.17g, bound %.17g, %d "
                "iterations against %.17g, %.17g, %d in one process\n",
                grid.py, grid.pz, stable.omega_max, stable.omega_bound, stable.iterations,
                expected.omega_max, expected.omega_bound, expected.iterations);
    return 1;
  }
  std::vector<double> buffers[4];
  for (int step = 0; step < SubdomainScenario::steps; ++step) {
    const bool report = step + 1 == SubdomainScenario::steps; // the last step reports energies
    if (rank == 0)
      whole.step(report);
    run.sim().step(report);
    exchange_halos(run, buffers);
  }
  const EnergySums energies = gather_energies(run);
  // (global id, x, y, z) of the owned nodes and (global id, h) of the owned bars, of every
  // rank, on rank 0.
  std::vector<double> nodes, bars;
  const Lattice& loc = run.sim().lattice();
  for (index_t n = 0; n < loc.num_nodes(); ++n)
    if (run.owns(n)) {
      const NodeAddress a = run.global_address(n);
      const Vec3 u = run.sim().displacement(n);
      const index_t g = a.centre ? lat.centre(a.i, a.j, a.k) : lat.corner(a.i, a.j, a.k);
      nodes.insert(nodes.end(), {double(g), u.x, u.y, u.z});
    }
  for (index_t b = 0; b < loc.num_bars(); ++b) {
    index_t g = 0;
    if (SubdomainScenario::owned_bar(run, lat, b, g))
      bars.insert(bars.end(), {double(g), run.sim().bar_state_value(0, b)});
  }
  nodes = gather_on_first(nodes);
  bars = gather_on_first(bars);
  double bad = 0;
  if (rank == 0) {
    for (std::size_t q = 0; q < nodes.size() && !bad; q += 4) {
      const auto id = static_cast<index_t>(nodes[q]);
      const Vec3 u = whole.displacement(id);
      if (u.x != nodes[q + 1] || u.y != nodes[q + 2] || u.z != nodes[q + 3]) {
        std::printf("mpi_check: node %u differs: (%.17g, %.17g, %.17g) against (%.17g, %.17g, "
                    "%.17g) in one process\n",
                    id, nodes[q + 1], nodes[q + 2], nodes[q + 3], u.x, u.y, u.z);
        bad = 1;
      }
    }
    for (std::size_t q = 0; q < bars.size() && !bad; q += 2) {
      const auto id = static_cast<index_t>(bars[q]);
      if (whole.bar_state_value(0, id) != bars[q + 1]) {
        std::printf("mpi_check: history of bar %u differs: %.17g against %.17g\n", id, bars[q + 1],
                    whole.bar_state_value(0, id));
        bad = 1;
      }
    }
    if (!bad && (nodes.size() != 4 * std::size_t{lat.num_nodes()} ||
                 bars.size() != 2 * std::size_t{lat.num_bars()} || whole.broken_count() == 0 ||
                 2 * whole.broken_count() > lat.num_bars())) {
      std::printf("mpi_check: %zu nodes and %zu bars owned (expected %u and %u), %llu bars "
                  "broken (expected some, not most)\n",
                  nodes.size() / 4, bars.size() / 2, lat.num_nodes(), lat.num_bars(),
                  static_cast<unsigned long long>(whole.broken_count()));
      bad = 1;
    }
    const EnergyReport& e = whole.last_report();
    // (The kinetic energy of imposed-velocity DOF is not in the rows: loaded runs compare the
    // other two.)
    if (!bad && (energies.elastic != e.elastic || energies.damage != e.damage_dissipated ||
                 (!loaded && energies.kinetic != e.kinetic))) {
      std::printf("mpi_check: energies differ: elastic %.17g, damage %.17g, kinetic %.17g "
                  "against %.17g, %.17g, %.17g in one process\n",
                  energies.elastic, energies.damage, energies.kinetic, e.elastic,
                  e.damage_dissipated, e.kinetic);
      bad = 1;
    }
    if (!bad)
      std::printf("mpi_check: %s body, %d x %d ranks, %zu nodes, %zu bar histories and the %s "
                  "energies identical to one process after %d steps (%llu bars broken), and the "
                  "stable step\n",
                  loaded ? "held, pulled and loaded" : "free", grid.py, grid.pz, nodes.size() / 4,
                  bars.size() / 2,
                  loaded ? "elastic and dissipated" : "elastic, dissipated and kinetic",
                  SubdomainScenario::steps, static_cast<unsigned long long>(whole.broken_count()));
  }
  broadcast_from_first(&bad, 1);
  return bad != 0 ? 1 : 0;
}

} // namespace

int main(int argc, char** argv) {
  ProcessGroup group(argc, argv);
  omp_set_num_threads(1);
  int bad = 0;
  for (const ProcessGrid grid : SubdomainScenario::grids(process_count()))
    bad |= check(false, grid) | check(true, grid);
  return bad;
}
