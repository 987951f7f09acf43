// The slab scenario across real MPI ranks (mpirun -np P): every rank steps its slab and
// exchanges its ghost planes through MPI; rank 0 also steps the whole body and compares
// every owned node's displacement and every owned bar's history, bit for bit.
// Exit code 0 when all agree, 1 at the first difference.
#include "parallel/comm.hpp"
#include "slab_scenario.hpp"

#include <cstdio>
#include <mpi.h>
#include <omp.h>

using namespace ldem;
using ldem::testing::SlabScenario;

int main(int argc, char** argv) {
  ProcessGroup group(argc, argv);
  const int rank = process_rank(), ranks = process_count();
  omp_set_num_threads(1);
  Simulation whole = SlabScenario::whole();
  const Lattice& lat = whole.lattice();
  SlabRun run = SlabScenario::slab(ranks, rank, whole.dt());
  std::vector<double> buffers[4];
  for (int step = 0; step < SlabScenario::steps; ++step) {
    if (rank == 0)
      whole.step();
    run.sim().step();
    exchange_halos(run, buffers);
  }
  // (global id, x, y, z) of owned nodes, then (global id, h, 0, 0) of owned bars.
  std::vector<double> mine;
  const Lattice& loc = run.sim().lattice();
  for (index_t n = 0; n < loc.num_nodes(); ++n)
    if (run.owns(n)) {
      const NodeAddress a = run.global_address(n);
      const Vec3 u = run.sim().displacement(n);
      mine.insert(mine.end(),
                  {double(a.centre ? lat.centre(a.i, a.j, a.k) : lat.corner(a.i, a.j, a.k)), u.x,
                   u.y, u.z});
    }
  const auto node_values = static_cast<int>(mine.size());
  for (index_t b = 0; b < loc.num_bars(); ++b) {
    index_t g = 0;
    if (SlabScenario::owned_bar(run, lat, b, g))
      mine.insert(mine.end(), {double(g), run.sim().bar_history(b), 0.0, 0.0});
  }
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), node_counts(counts.size()),
      offsets(counts.size());
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Gather(&node_values, 1, MPI_INT, node_counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  int total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    offsets[r] = total;
    total += counts[r];
  }
  std::vector<double> all(rank == 0 ? static_cast<std::size_t>(total) : 0);
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE,
              0, MPI_COMM_WORLD);
  int bad = 0;
  if (rank == 0) {
    std::size_t nodes = 0, bars = 0;
    for (std::size_t r = 0; r < counts.size() && !bad; ++r)
      for (int q = 0; q < counts[r] && !bad; q += 4) {
        const double* v = &all[static_cast<std::size_t>(offsets[r] + q)];
        const auto id = static_cast<index_t>(v[0]);
        if (q < node_counts[r]) {
          ++nodes;
          const Vec3 u = whole.displacement(id);
          if (u.x != v[1] || u.y != v[2] || u.z != v[3]) {
            std::printf("mpi_check: node %u of rank %zu differs: (%.17g, %.17g, %.17g) against "
                        "(%.17g, %.17g, %.17g) in one process\n",
                        id, r, v[1], v[2], v[3], u.x, u.y, u.z);
            bad = 1;
          }
        } else {
          ++bars;
          if (whole.bar_history(id) != v[1]) {
            std::printf("mpi_check: history of bar %u of rank %zu differs: %.17g against %.17g\n",
                        id, r, v[1], whole.bar_history(id));
            bad = 1;
          }
        }
      }
    if (!bad && (nodes != lat.num_nodes() || whole.broken_count() == 0 ||
                 2 * whole.broken_count() > lat.num_bars())) {
      std::printf("mpi_check: %zu nodes owned (expected %u), %llu bars broken (expected some, "
                  "not most)\n",
                  nodes, lat.num_nodes(), static_cast<unsigned long long>(whole.broken_count()));
      bad = 1;
    }
    if (!bad)
      std::printf("mpi_check: %d ranks, %zu nodes and %zu bar histories identical to one "
                  "process after %d steps (%llu bars broken)\n",
                  ranks, nodes, bars, SlabScenario::steps,
                  static_cast<unsigned long long>(whole.broken_count()));
  }
  MPI_Bcast(&bad, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return bad;
}
