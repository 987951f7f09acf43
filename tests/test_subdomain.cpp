// Decomposition into boxes over y and z (src/parallel/subdomain.hpp): the windows and the grid,
// and subdomains stepped side by side in one process, exchanging their ghost nodes in memory
// as ranks do through MPI, move every owned node and every owned bar's history bit for bit as
// the whole body does, on every grid of 1 to 8 processes that fits the body.
#include "subdomain_scenario.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cstdint>
#include <gtest/gtest.h>
#include <memory>

namespace ldem::testing {
namespace {

TEST(Subdomain, OwnedModulesAndWindows) {
  // 10 modules over 3 parts: c n / C gives [0, 3), [3, 6), [6, 10); one ghost module each
  // side, clipped to the body.
  const index_t m0[] = {0, 3, 6}, m1[] = {3, 6, 10}, w0[] = {0, 2, 5}, w1[] = {4, 7, 10};
  for (int c = 0; c < 3; ++c) {
    const AxisPart a = split_axis(10, 3, c);
    EXPECT_EQ(a.m0, m0[c]);
    EXPECT_EQ(a.m1, m1[c]);
    EXPECT_EQ(a.w0, w0[c]);
    EXPECT_EQ(a.w1, w1[c]);
  }
  EXPECT_EQ(split_axis(4, 1, 0).local_n(), 4u);
  // Rank = cy + Py cz: rank 5 of a 2 x 3 grid is (1, 2).
  const Subdomain s = make_subdomain(6, 9, ProcessGrid{2, 3}, 5);
  EXPECT_EQ(s.y.coord, 1);
  EXPECT_EQ(s.z.coord, 2);
  EXPECT_EQ(s.neighbour(1, -1), 4);
  EXPECT_EQ(s.neighbour(1, +1), -1);
  EXPECT_EQ(s.neighbour(2, -1), 3);
  EXPECT_EQ(s.neighbour(2, +1), -1);
  EXPECT_THROW(make_subdomain(4, 2, ProcessGrid{1, 3}, 0), InputError); // 2 modules, 3 boxes
  EXPECT_THROW(make_subdomain(8, 8, ProcessGrid{1, 2}, 2), InputError); // no such rank
}

// The grid cuts the least area: (Py - 1) nz + (Pz - 1) ny modules on the cut faces.
TEST(Subdomain, GridCutsTheLeastArea) {
  const auto grid = [](index_t ny, index_t nz, int ranks) {
    const ProcessGrid g = choose_grid(ny, nz, ranks);
    return std::pair{g.py, g.pz};
  };
  EXPECT_EQ(grid(64, 64, 2), std::pair(1, 2)); // 64 either way: slabs along z on a tie
  EXPECT_EQ(grid(64, 64, 4), std::pair(2, 2)); // 64 + 64 against 3 x 64
  EXPECT_EQ(grid(64, 64, 8), std::pair(2, 4)); // 64 + 3 x 64 against 3 x 64 + 64: tie
  EXPECT_EQ(grid(1, 41, 3), std::pair(1, 3));  // the paper's x-z plate: only along z
  EXPECT_EQ(grid(60, 1, 4), std::pair(4, 1));  // a plate in x-y: only along y
  EXPECT_EQ(grid(4, 7, 4), std::pair(2, 2));   // 7 + 4 against 3 x 4 = 12 and 3 x 7 = 21
  EXPECT_EQ(grid(1000, 1000, 1024), std::pair(32, 32));
  // None fits: the message names the key and what would.
  try {
    choose_grid(4, 4, 7); // 7 is prime and above 4
    ADD_FAILURE() << "7 processes on 4 x 4 modules should be refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lattice.modules"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Start 6 processes"), std::string::npos) << e.what();
  }
  EXPECT_THROW(choose_grid(1, 1, 2), InputError); // a bar of modules along x
}

// owner_rank agrees with every subdomain's own view of what it owns.
TEST(Subdomain, OwnerRankIsTheSubdomainThatOwns) {
  for (const ProcessGrid g :
       {ProcessGrid{1, 1}, ProcessGrid{2, 3}, ProcessGrid{4, 1}, ProcessGrid{3, 7}}) {
    std::vector<Subdomain> subs;
    for (int r = 0; r < g.py * g.pz; ++r)
      subs.push_back(make_subdomain(5, 7, g, r));
    for (index_t k = 0; k <= 7; ++k)
      for (index_t j = 0; j <= 5; ++j) {
        const int owner = owner_rank(subs[0], j, k);
        for (const Subdomain& s : subs)
          ASSERT_EQ(s.owns(j, k, true), s.rank == owner)
              << g.py << " x " << g.pz << ", (j, k) = (" << j << ", " << k << ")";
      }
  }
}

// A shaped body's cuts balance its present modules: a wedge of 20 x 1 x 20 modules whose layer
// k holds k + 1 present modules; two parts along z split them at the layer where the sum reaches
// half (k = 14: 1 + ... + 14 = 105 of 210), not at 10. Every part keeps at least one layer, and
// owner_rank agrees with the cuts.
TEST(Subdomain, ShapedBodiesAreCutToShareThePresentModules) {
  Lattice lat(20, 1, 20, 1.0);
  auto mask = std::make_shared<std::vector<std::uint8_t>>(20 * 20, 0);
  for (index_t k = 0; k < 20; ++k)
    for (index_t i = 0; i <= k; ++i)
      (*mask)[i + 20 * k] = 1;
  lat.set_modules(mask);
  const Subdomain lower = make_subdomain(lat, ProcessGrid{1, 2}, 0);
  const Subdomain upper = make_subdomain(lat, ProcessGrid{1, 2}, 1);
  EXPECT_EQ(lower.z.m0, 0u);
  EXPECT_EQ(lower.z.m1, 14u); // sum of (k + 1) for k < 14: 105, half of 210
  EXPECT_EQ(upper.z.m0, 14u);
  EXPECT_EQ(upper.z.m1, 20u);
  for (index_t k = 0; k <= 20; ++k)
    EXPECT_EQ(owner_rank(lower, 0, k), k < 14 ? 0 : 1) << k;
  // Weights all in the last layer: every part still keeps a layer.
  std::vector<std::uint64_t> w(6, 0);
  w[5] = 10;
  for (int c = 0; c < 4; ++c) {
    const AxisPart a = split_axis(6, 4, c, &w);
    EXPECT_GE(a.m1, a.m0 + 1) << c;
  }
  EXPECT_EQ(split_axis(6, 4, 3, &w).m1, 6u);
  // A box is cut as before.
  const Subdomain box = make_subdomain(Lattice(20, 1, 20, 1.0), ProcessGrid{1, 2}, 0);
  EXPECT_EQ(box.z.m1, 10u);
}

// The spans that carry states between the subdomains and the whole body (snapshots,
// checkpoints, resumes): the owned spans of all subdomains cover every node and bar of the
// body exactly once, a
// window's spans cover its lattice exactly once, and each span maps a window's number to the
// body's number of the same node or bar.
TEST(Subdomain, SpansCoverTheBodyOnceAndMapWindowToBody) {
  using S = SubdomainScenario;
  const Lattice whole(S::nx, S::ny, S::nz, 0.01);
  for (int ranks = 1; ranks <= 8; ++ranks)
    for (const ProcessGrid grid : S::grids(ranks)) {
      const std::string name = std::to_string(grid.py) + " x " + std::to_string(grid.pz);
      std::vector<int> node_owners(whole.num_nodes(), 0), bar_owners(whole.num_bars(), 0);
      for (int r = 0; r < ranks; ++r) {
        const Subdomain sub = make_subdomain(whole.ny(), whole.nz(), grid, r);
        const Lattice local = window_lattice(sub, whole);
        for (const Span& s : subdomain_node_spans(sub, whole, true))
          for (index_t q = 0; q < s.count; ++q)
            ++node_owners[s.global_first + q];
        for (const Span& s : subdomain_bar_spans(sub, whole, true))
          for (index_t q = 0; q < s.count; ++q)
            ++bar_owners[s.global_first + q];
        std::vector<int> local_nodes(local.num_nodes(), 0), local_bars(local.num_bars(), 0);
        for (const Span& s : subdomain_node_spans(sub, whole, false))
          for (index_t q = 0; q < s.count; ++q) {
            ++local_nodes[s.local_first + q];
            NodeAddress a = local.node_address(s.local_first + q);
            a.j += sub.y.w0;
            a.k += sub.z.w0;
            ASSERT_EQ(s.global_first + q,
                      a.centre ? whole.centre(a.i, a.j, a.k) : whole.corner(a.i, a.j, a.k));
          }
        for (const Span& s : subdomain_bar_spans(sub, whole, false))
          for (index_t q = 0; q < s.count; ++q) {
            ++local_bars[s.local_first + q];
            ASSERT_EQ(s.global_first + q, global_bar(sub, local, whole, s.local_first + q));
          }
        EXPECT_EQ(std::count(local_nodes.begin(), local_nodes.end(), 1), local.num_nodes())
            << name << ", rank " << r;
        EXPECT_EQ(std::count(local_bars.begin(), local_bars.end(), 1), local.num_bars())
            << name << ", rank " << r;
      }
      EXPECT_EQ(std::count(node_owners.begin(), node_owners.end(), 1), whole.num_nodes()) << name;
      EXPECT_EQ(std::count(bar_owners.begin(), bar_owners.end(), 1), whole.num_bars()) << name;
    }
}

// Every rank's ghost nodes from its neighbours, along y for all, then along z for all, as
// exchange_halos does through MPI.
void exchange_in_memory(std::vector<SubdomainRun>& runs) {
  std::vector<double> buf;
  for (int axis : {1, 2})
    for (SubdomainRun& run : runs)
      for (int dir : {-1, +1})
        if (const int other = run.subdomain().neighbour(axis, dir); other >= 0) {
          run.pack(axis, dir, buf);
          runs[static_cast<std::size_t>(other)].unpack(axis, -dir, buf);
        }
}

void expect_subdomains_match_whole_body(ProcessGrid grid, bool loaded) {
  using S = SubdomainScenario;
  Simulation whole = S::whole(loaded);
  const Lattice& lat = whole.lattice();
  std::vector<SubdomainRun> runs;
  for (int r = 0; r < grid.py * grid.pz; ++r)
    runs.push_back(S::subdomain(grid, r, whole.dt(), loaded));
  for (int step = 0; step < S::steps; ++step) {
    const bool report = step + 1 == S::steps; // the last step reports its energies
    whole.step(report);
    for (SubdomainRun& s : runs)
      s.sim().step(report);
    exchange_in_memory(runs);
  }
  ASSERT_GT(whole.broken_count(), 0u) << "the run should break bars";
  ASSERT_LT(whole.broken_count(), std::uint64_t{lat.num_bars()} / 2) << "but not most of them";
  std::size_t owned = 0, owned_bars = 0;
  for (const SubdomainRun& s : runs) {
    const Lattice& loc = s.sim().lattice();
    const int rank = s.subdomain().rank;
    for (index_t n = 0; n < loc.num_nodes(); ++n) {
      if (!s.owns(n))
        continue;
      ++owned;
      const NodeAddress a = s.global_address(n);
      const index_t g = a.centre ? lat.centre(a.i, a.j, a.k) : lat.corner(a.i, a.j, a.k);
      const Vec3 u = s.sim().displacement(n), v = whole.displacement(g);
      ASSERT_EQ(u.x, v.x) << "rank " << rank << " node " << g;
      ASSERT_EQ(u.y, v.y) << "rank " << rank << " node " << g;
      ASSERT_EQ(u.z, v.z) << "rank " << rank << " node " << g;
    }
    for (index_t b = 0; b < loc.num_bars(); ++b) {
      index_t g = 0;
      if (S::owned_bar(s, lat, b, g)) {
        ++owned_bars;
        for (std::size_t a = 0; a < whole.bar_state_arrays().size(); ++a)
          ASSERT_EQ(s.sim().bar_state_value(a, b), whole.bar_state_value(a, g))
              << "rank " << rank << " bar " << g << " " << whole.bar_state_arrays()[a].name;
      }
    }
  }
  EXPECT_EQ(owned, std::size_t{lat.num_nodes()}); // every node owned exactly once
  EXPECT_EQ(owned_bars, std::size_t{lat.num_bars()});
  // The energies: the subdomains' owned rows, in rank order, summed in the body's row order.
  EnergyRows rows;
  for (const SubdomainRun& s : runs)
    s.append_owned_energy_rows(rows);
  const std::vector<std::size_t> bars = key_order(rows.bar_keys);
  ExactSum kinetic; // as one process sums it (Ledger)
  for (double x : rows.kinetic)
    kinetic.add(x);
  const EnergyReport& e = whole.last_report();
  EXPECT_GT(e.damage_dissipated, 0.0);
  EXPECT_EQ(sum_in_order(rows.elastic, bars), e.elastic);
  EXPECT_EQ(sum_in_order(rows.damage, bars), e.damage_dissipated);
  if (!loaded) { // the kinetic energy of imposed-velocity DOF is not in the rows (not gathered)
    EXPECT_EQ(kinetic.value(), e.kinetic);
  }
}

void expect_every_grid_matches(bool loaded) {
  for (int ranks = 1; ranks <= 8; ++ranks)
    for (const ProcessGrid grid : SubdomainScenario::grids(ranks)) {
      SCOPED_TRACE(std::to_string(grid.py) + " x " + std::to_string(grid.pz));
      expect_subdomains_match_whole_body(grid, loaded);
    }
}

TEST(Subdomain, SubdomainsStepBitForBitLikeTheWholeBody) {
  expect_every_grid_matches(false);
}

// The same with the body held, pulled and loaded (subdomain_conditions: each rank applies the
// conditions to the nodes it owns) and damped.
TEST(Subdomain, SubdomainsWithConditionsStepBitForBitLikeTheWholeBody) {
  expect_every_grid_matches(true);
}

} // namespace
} // namespace ldem::testing
