// A small body strained until bars soften and break, stepped whole or as subdomains: shared by
// the in-process test (test_subdomain.cpp) and the MPI check (mpi_check.cpp).
#pragma once

#include "helpers.hpp"
#include "parallel/subdomain.hpp"

#include <random>

namespace ldem::testing {

struct SubdomainScenario {
  static constexpr index_t nx = 5, ny = 4, nz = 7;
  static constexpr int steps = 300;
  // e_p = 1e-3, random displacements of 1e-3 L and velocities of 1e-4 c: strains of a few
  // 1e-3, so that some bars soften and about a tenth break during the run, on both sides of
  // the subdomains' boundaries.
  static MaterialSpec material() { return unit_material(1e-3, 3.0); }

  // Random displacement or velocity of node (i, j, k), the same draw in every process.
  static Vec3 draw(std::uint64_t seed, const NodeAddress& a, double amplitude) {
    std::mt19937_64 rng(seed ^
                        (a.i + 1000003ull * (a.j + 1000003ull * (a.k + 7919ull * a.centre))));
    std::uniform_real_distribution<double> u(-amplitude, amplitude);
    const double x = u(rng), y = u(rng), z = u(rng);
    return {x, y, z};
  }

  // The initial state of a node whose address in the whole body is `a`.
  static void start(Simulation& sim, index_t node, const NodeAddress& a) {
    sim.set_displacement(node, draw(1, a, 1e-3));
    sim.set_half_step_velocity(node, draw(2, a, 1e-4));
  }

  // With `loaded`, the body is also held and driven: its bottom face fixed, its top face
  // pulled up at a velocity that ramps in, a constant traction on face x+ (each node weighted
  // by its area, so that the subdomains take their nodes' weights), and mass-proportional
  // damping.
  static Conditions conditions(const Lattice& whole, bool loaded) {
    Conditions c;
    if (!loaded)
      return c;
    c.fixed.push_back({face(whole, Face::ZMin), kDofAll});
    c.velocities.push_back(
        {face(whole, Face::ZMax), kDofZ, {0, 0, 1e-4}, TimeFunction({LinearRamp{1.0, 20.0}})});
    c.loads.push_back({face(whole, Face::XMax), {2e-5, 0, 0}, TimeFunction{},
                       face_tributary_areas(whole, Face::XMax)});
    return c;
  }
  static SolverOptions options(bool loaded) {
    SolverOptions o;
    o.damping = loaded ? 0.01 : 0.0;
    return o;
  }

  static Simulation whole(bool loaded = false) {
    const Lattice lat(nx, ny, nz, 1.0);
    Simulation sim =
        make_sim(nx, ny, nz, 1.0, material(), conditions(lat, loaded), options(loaded));
    for (index_t n = 0; n < sim.lattice().num_nodes(); ++n)
      start(sim, n, sim.lattice().node_address(n));
    return sim;
  }

  // The grids of `ranks` processes that fit the body (Py <= ny, Pz <= nz).
  static std::vector<ProcessGrid> grids(int ranks) {
    std::vector<ProcessGrid> out;
    for (int py = 1; py <= ranks; ++py)
      if (ranks % py == 0 && py <= int{ny} && ranks / py <= int{nz})
        out.push_back({py, ranks / py});
    return out;
  }

  // Rank `rank` of a grid of processes, with the whole body's time step `dt`, started.
  static SubdomainRun subdomain(ProcessGrid grid, int rank, double dt, bool loaded = false) {
    const Subdomain s = make_subdomain(ny, nz, grid, rank);
    const Lattice whole(nx, ny, nz, 1.0);
    Lattice local = window_lattice(s, whole);
    BarTable table(local, material());
    SolverOptions given = options(loaded);
    given.step.rule = TimeStep::Rule::Given;
    given.step.dt = dt;
    Conditions c = subdomain_conditions(s, whole, local, conditions(whole, loaded));
    SubdomainRun run(s, std::move(local), std::move(table), std::move(c), given);
    for (index_t n = 0; n < run.sim().lattice().num_nodes(); ++n)
      start(run.sim(), n, run.global_address(n));
    return run;
  }

  // Whether bar `b` of the subdomain's window is one it owns, and its number in the whole
  // body (lattice `whole`).
  static bool owned_bar(const SubdomainRun& run, const Lattice& whole, index_t b, index_t& global) {
    global = global_bar(run.subdomain(), run.sim().lattice(), whole, b);
    return run.owns_bar(b);
  }
};

} // namespace ldem::testing
