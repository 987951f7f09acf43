// Slab decomposition along z (src/parallel/slab.hpp): the windows, and slabs stepped side by
// side in one process, exchanging their ghost planes in memory as ranks do through MPI, move
// every owned node and every owned bar's history bit for bit as the whole body does.
#include "slab_scenario.hpp"
#include "util/error.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace ldem::testing {
namespace {

TEST(Slab, OwnedModulesAndWindows) {
  // 10 modules over 3 ranks: p nz / P gives [0, 3), [3, 6), [6, 10); one ghost module each
  // side, clipped to the body.
  const index_t m0[] = {0, 3, 6}, m1[] = {3, 6, 10}, w0[] = {0, 2, 5}, w1[] = {4, 7, 10};
  for (int r = 0; r < 3; ++r) {
    const Slab s = make_slab(10, 3, r);
    EXPECT_EQ(s.m0, m0[r]);
    EXPECT_EQ(s.m1, m1[r]);
    EXPECT_EQ(s.w0, w0[r]);
    EXPECT_EQ(s.w1, w1[r]);
  }
  EXPECT_EQ(make_slab(4, 1, 0).local_nz(), 4u);
  EXPECT_THROW(make_slab(2, 3, 0), InputError); // fewer modules than ranks
  EXPECT_THROW(make_slab(8, 2, 2), InputError); // no such rank
}

// The spans that carry states between the slabs and the whole body (snapshots, checkpoints,
// resumes): the owned spans of all slabs cover every node and bar of the body exactly once, a
// window's spans cover its lattice exactly once, and each span maps a window's number to the
// body's number of the same node or bar.
TEST(Slab, SpansCoverTheBodyOnceAndMapWindowToBody) {
  const Lattice whole(5, 4, 7, 0.01);
  for (int ranks = 1; ranks <= 4; ++ranks) {
    std::vector<int> node_owners(whole.num_nodes(), 0), bar_owners(whole.num_bars(), 0);
    for (int r = 0; r < ranks; ++r) {
      const Slab slab = make_slab(whole.nz(), ranks, r);
      const Lattice local = window_lattice(slab, whole);
      for (const Span& s : slab_node_spans(slab, whole, true))
        for (index_t q = 0; q < s.count; ++q)
          ++node_owners[s.global_first + q];
      for (const Span& s : slab_bar_spans(slab, whole, true))
        for (index_t q = 0; q < s.count; ++q)
          ++bar_owners[s.global_first + q];
      std::vector<int> local_nodes(local.num_nodes(), 0), local_bars(local.num_bars(), 0);
      for (const Span& s : slab_node_spans(slab, whole, false))
        for (index_t q = 0; q < s.count; ++q) {
          ++local_nodes[s.local_first + q];
          NodeAddress a = local.node_address(s.local_first + q);
          a.k += slab.w0;
          ASSERT_EQ(s.global_first + q, a.centre ? whole.centre(a.i, a.j, a.k)
                                                 : whole.corner(a.i, a.j, a.k));
        }
      for (const Span& s : slab_bar_spans(slab, whole, false))
        for (index_t q = 0; q < s.count; ++q) {
          ++local_bars[s.local_first + q];
          ASSERT_EQ(s.global_first + q, global_bar(slab, local, whole, s.local_first + q));
        }
      EXPECT_EQ(std::count(local_nodes.begin(), local_nodes.end(), 1), local.num_nodes())
          << ranks << " ranks, rank " << r;
      EXPECT_EQ(std::count(local_bars.begin(), local_bars.end(), 1), local.num_bars())
          << ranks << " ranks, rank " << r;
    }
    EXPECT_EQ(std::count(node_owners.begin(), node_owners.end(), 1), whole.num_nodes())
        << ranks << " ranks";
    EXPECT_EQ(std::count(bar_owners.begin(), bar_owners.end(), 1), whole.num_bars())
        << ranks << " ranks";
  }
}

void expect_slabs_match_whole_body(int ranks, bool loaded) {
  using S = SlabScenario;
  Simulation whole = S::whole(loaded);
  const Lattice& lat = whole.lattice();
  std::vector<SlabRun> slabs;
  for (int r = 0; r < ranks; ++r)
    slabs.push_back(S::slab(ranks, r, whole.dt(), loaded));
  std::vector<double> buf;
  for (int step = 0; step < S::steps; ++step) {
    const bool report = step + 1 == S::steps; // the last step reports its energies
    whole.step(report);
    for (SlabRun& s : slabs)
      s.sim().step(report);
    for (int r = 1; r < ranks; ++r) { // r's bottom planes to r - 1, r - 1's top planes to r
      slabs[r].pack(-1, buf);
      slabs[r - 1].unpack(+1, buf);
      slabs[r - 1].pack(+1, buf);
      slabs[r].unpack(-1, buf);
    }
  }
  ASSERT_GT(whole.broken_count(), 0u) << "the run should break bars";
  ASSERT_LT(whole.broken_count(), std::uint64_t{lat.num_bars()} / 2) << "but not most of them";
  std::size_t owned = 0;
  for (const SlabRun& s : slabs) {
    const Lattice& loc = s.sim().lattice();
    for (index_t n = 0; n < loc.num_nodes(); ++n) {
      if (!s.owns(n))
        continue;
      ++owned;
      const NodeAddress a = s.global_address(n);
      const index_t g = a.centre ? lat.centre(a.i, a.j, a.k) : lat.corner(a.i, a.j, a.k);
      const Vec3 u = s.sim().displacement(n), v = whole.displacement(g);
      ASSERT_EQ(u.x, v.x) << "rank " << s.slab().rank << " node " << g;
      ASSERT_EQ(u.y, v.y) << "rank " << s.slab().rank << " node " << g;
      ASSERT_EQ(u.z, v.z) << "rank " << s.slab().rank << " node " << g;
    }
    // Histories of the bars of the owned bar planes.
    for (index_t b = 0; b < loc.num_bars(); ++b) {
      index_t g = 0;
      if (S::owned_bar(s, lat, b, g)) {
        ASSERT_EQ(s.sim().bar_history(b), whole.bar_history(g))
            << "rank " << s.slab().rank << " bar " << g;
      }
    }
  }
  EXPECT_EQ(owned, std::size_t{lat.num_nodes()}); // every node owned exactly once
  // The energies: the slabs' owned rows, slab after slab, summed in order.
  std::vector<double> elastic, damage, kinetic;
  for (const SlabRun& s : slabs)
    s.append_owned_energy_rows(elastic, damage, kinetic);
  const EnergyReport& e = whole.last_report();
  EXPECT_GT(e.damage_dissipated, 0.0);
  EXPECT_EQ(S::ordered_sum(elastic), e.elastic);
  EXPECT_EQ(S::ordered_sum(damage), e.damage_dissipated);
  if (!loaded) { // the kinetic energy of imposed-velocity DOF is not in the rows (not gathered)
    EXPECT_EQ(S::ordered_sum(kinetic), e.kinetic);
  }
}

TEST(Slab, SlabsStepBitForBitLikeTheWholeBody) {
  for (int ranks = 1; ranks <= 4; ++ranks) {
    SCOPED_TRACE(ranks);
    expect_slabs_match_whole_body(ranks, false);
  }
}

// The same with the body held, pulled and loaded (slab_conditions: each rank applies the
// conditions to the nodes it owns) and damped.
TEST(Slab, SlabsWithConditionsStepBitForBitLikeTheWholeBody) {
  for (int ranks = 1; ranks <= 4; ++ranks) {
    SCOPED_TRACE(ranks);
    expect_slabs_match_whole_body(ranks, true);
  }
}

} // namespace
} // namespace ldem::testing
