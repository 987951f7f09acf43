// Tests of initial cracks (SPEC section 2, "Boundary conditions and loads": every bar whose
// segment crosses a given surface starts broken; a surface through a plane of nodes
// separates nothing) and of the connectivity check that uses them.
#include "lattice/lattice.hpp"
#include "lattice/precrack.hpp"
#include "material/bar_table.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <string>
#include <vector>

namespace ldem {
namespace {

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A rectangle in the plane z = z0 covering x in [x0, x1], y in [y0, y1].
Rectangle horizontal(double z0, double x0, double x1, double y0, double y1,
                     std::string name = "crack") {
  return {std::move(name), {x0, y0, z0}, {x1 - x0, 0, 0}, {0, y1 - y0, 0}};
}

// Rectangle over the whole x-y cross-section of the box at height z0.
Rectangle cross_section(const Lattice& lat, double z0) {
  return horizontal(z0, 0, lat.nx() * lat.L(), 0, lat.ny() * lat.L());
}

std::string refusal(const Lattice& lat, const Rectangle& r, bool nudge) {
  try {
    cut_bars(lat, r, nudge);
  } catch (const InputError& e) {
    return e.what();
  }
  return "<accepted>";
}

// The bars crossing the plane z = (k + 1/4) L, 0 <= k < nz, of an nx x ny x nz box. The
// plane lies inside module layer k (z in [k L, (k+1) L]):
//  - the vertical edges of layer k, EdgeZ (i, j, k): z from k L to (k+1) L, all
//    (nx + 1)(ny + 1) of them;
//  - the centre-centre bars CentreZ (i, j, k-1) from the centres of layer k-1 at
//    (k - 1/2) L to those of layer k at (k + 1/2) L: nx ny of them, but only if k >= 1
//    (layer 0 has no layer below it);
//  - the 4 diagonals per module of layer k from its centre at (k + 1/2) L down to its lower
//    corners at k L (families Diag0..Diag3, whose z bit is 0): 4 nx ny;
//  - nothing else: EdgeX/EdgeY lie in the planes z = m L, CentreX/CentreY in z = (m + 1/2) L,
//    the upper diagonals of layer k span [(k + 1/2) L, (k + 1) L] and those of the other
//    layers miss (k L, (k + 1/2) L) entirely.
// Total (nx + 1)(ny + 1) + [k >= 1] nx ny + 4 nx ny.
std::vector<index_t> bars_crossing_layer(const Lattice& lat, index_t k) {
  std::vector<index_t> bars;
  for (index_t j = 0; j <= lat.ny(); ++j)
    for (index_t i = 0; i <= lat.nx(); ++i)
      bars.push_back(lat.bar(Family::EdgeZ, i, j, k));
  for (index_t j = 0; j < lat.ny(); ++j)
    for (index_t i = 0; i < lat.nx(); ++i) {
      if (k >= 1)
        bars.push_back(lat.bar(Family::CentreZ, i, j, k - 1));
      for (int c = 0; c < 4; ++c)
        bars.push_back(lat.bar(static_cast<Family>(static_cast<int>(Family::Diag0) + c), i, j, k));
    }
  std::sort(bars.begin(), bars.end());
  return bars;
}

// Independent reference for any horizontal rectangle: a bar crosses it if its end nodes lie
// strictly on both sides of z0 and the point where its segment meets the plane has
// x0 <= x <= x1 and y0 <= y <= y1.
std::vector<index_t> brute_force_horizontal(const Lattice& lat, double z0, double x0, double x1,
                                            double y0, double y1) {
  const double tol = 1e-9 * lat.L();
  std::vector<index_t> bars;
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    const auto n = lat.bar_nodes(bar);
    const Vec3 a = lat.position(n[0]), b = lat.position(n[1]);
    if (!((a.z < z0 && b.z > z0) || (a.z > z0 && b.z < z0)))
      continue;
    const double t = (z0 - a.z) / (b.z - a.z);
    const double x = a.x + t * (b.x - a.x), y = a.y + t * (b.y - a.y);
    if (x >= x0 - tol && x <= x1 + tol && y >= y0 - tol && y <= y1 + tol)
      bars.push_back(bar);
  }
  return bars;
}

// ---------------------------------------------------------------------------------------
// Refusals and nudging

TEST(Precrack, RectangleThroughNodePlaneIsRefused) {
  const double L = 0.5;
  const Lattice lat(3, 2, 4, L);
  Rectangle r = cross_section(lat, 2 * L);
  r.name = "mid_crack";
  const std::string msg = refusal(lat, r, false);
  EXPECT_TRUE(contains(msg, "plane of nodes")) << msg;
  EXPECT_TRUE(contains(msg, "mid_crack")) << msg;
  // Why: the vertical edges of layers 1 and 2 and the diagonals of their modules only end
  // on z = 2 L; the only bars crossing it are the 3 x 2 centre-centre bars CentreZ (i, j, 1)
  // from (1.5 L) to (2.5 L), and without them the body still hangs together through the
  // edges and diagonals, so such a crack would separate nothing.
  const std::vector<index_t> crossing = brute_force_horizontal(lat, 2 * L, 0, 3 * L, 0, 2 * L);
  EXPECT_EQ(crossing.size(), 6u);
  for (index_t bar : crossing)
    EXPECT_EQ(lat.bar_address(bar).family, Family::CentreZ);
  index_t count = 0;
  connected_components(lat, crossing, &count);
  EXPECT_EQ(count, 1u);
}

// Nudged by L/4 along the unit normal edge1 x edge2 = +z: z = 2 L -> 2.25 L, which cuts the
// bars crossing layer k = 2 exactly as a rectangle placed there directly.
TEST(Precrack, NudgeMovesByQuarterModuleAndCuts) {
  const double L = 0.5;
  const Lattice lat(3, 2, 4, L);
  const CutResult nudged = cut_bars(lat, cross_section(lat, 2 * L), true);
  EXPECT_TRUE(nudged.nudged);
  EXPECT_NEAR(nudged.origin.x, 0.0, 1e-15);
  EXPECT_NEAR(nudged.origin.y, 0.0, 1e-15);
  EXPECT_NEAR(nudged.origin.z, 2.25 * L, 1e-15);
  const CutResult direct = cut_bars(lat, cross_section(lat, 2.25 * L), false);
  EXPECT_FALSE(direct.nudged);
  EXPECT_NEAR(direct.origin.z, 2.25 * L, 1e-15);
  EXPECT_EQ(nudged.bars, direct.bars);
  EXPECT_EQ(nudged.bars, bars_crossing_layer(lat, 2));

  // Flipping the edges flips the normal: edge2 x edge1 = -z, so z = 2 L -> 1.75 L, which
  // lies in layer 1 at (1 + 3/4) L. By the mirror image of bars_crossing_layer's count:
  // (3+1)(2+1) vertical edges, 3 x 2 centre-centre bars (layers 1-2) and 4 upper diagonals
  // per module: 12 + 6 + 24 = 42.
  const Rectangle base = cross_section(lat, 2 * L);
  const Rectangle flipped{"flipped", base.origin, base.edge2, base.edge1};
  const CutResult down = cut_bars(lat, flipped, true);
  EXPECT_NEAR(down.origin.z, 1.75 * L, 1e-15);
  EXPECT_EQ(down.bars.size(), 42u);
  EXPECT_EQ(down.bars, brute_force_horizontal(lat, 1.75 * L, 0, 3 * L, 0, 2 * L));
}

TEST(Precrack, RectangleOutsideTheBodyOrDegenerateIsRefused) {
  const double L = 0.5;
  const Lattice lat(3, 2, 4, L);
  // Above the body (z = 5.25 L > 4 L).
  std::string msg = refusal(lat, horizontal(5.25 * L, 0, 3 * L, 0, 2 * L, "above"), false);
  EXPECT_TRUE(contains(msg, "above")) << msg;
  EXPECT_TRUE(contains(msg, "outside")) << msg;
  // Beside it (x in [4 L, 6 L] while the body ends at 3 L), at a height between node planes.
  msg = refusal(lat, horizontal(1.25 * L, 4 * L, 6 * L, 0, 2 * L, "beside"), false);
  EXPECT_TRUE(contains(msg, "beside")) << msg;
  // Parallel edges span no rectangle.
  const Rectangle flat{"flat", {0, 0, 1.25 * L}, {L, 0, 0}, {2 * L, 0, 0}};
  EXPECT_THROW(cut_bars(lat, flat, false), InputError);
}

// ---------------------------------------------------------------------------------------
// Full cross-section cuts: exact bar sets, separation, energy

TEST(Precrack, CrossSectionCutsExactlyTheCrossingBars) {
  struct Box {
    index_t nx, ny, nz;
  };
  for (const Box& b : {Box{3, 2, 4}, Box{1, 1, 3}, Box{5, 1, 2}, Box{2, 3, 3}}) {
    const double L = 0.2;
    const Lattice lat(b.nx, b.ny, b.nz, L);
    for (index_t k = 0; k < b.nz; ++k) {
      SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz << ", k = " << k);
      const double z0 = (k + 0.25) * L;
      const CutResult cut = cut_bars(lat, cross_section(lat, z0), false);
      EXPECT_FALSE(cut.nudged);
      const std::size_t want_count =
          (b.nx + 1) * (b.ny + 1) + (k >= 1 ? b.nx * b.ny : 0) + 4 * b.nx * b.ny;
      EXPECT_EQ(cut.bars.size(), want_count);
      EXPECT_EQ(cut.bars, bars_crossing_layer(lat, k));
      EXPECT_EQ(cut.bars, brute_force_horizontal(lat, z0, 0, b.nx * L, 0, b.ny * L));

      // Removing them leaves exactly two pieces: the nodes below z0 and those above.
      index_t count = 0;
      const std::vector<index_t> label = connected_components(lat, cut.bars, &count);
      EXPECT_EQ(count, 2u);
      const index_t below = label[lat.corner(0, 0, 0)], above = label[lat.corner(0, 0, b.nz)];
      EXPECT_NE(below, above);
      for (index_t n = 0; n < lat.num_nodes(); ++n)
        EXPECT_EQ(label[n], lat.position(n).z < z0 ? below : above) << "node " << n;
    }
  }
}

// SPEC: "a module split in two by a plane parallel to a face dissipates exactly Gf L^2".
// Summing the rupture dissipation (area factor) x Gf x A^f over the bars of
// bars_crossing_layer: the vertical edges' area factors add up to nx ny (4 edges x 1/4 per
// module), so for k >= 1
//   Gf L^2 nx ny (3/22 [edges] + 3/22 [centre-centre] + 4 x 4/22 [diagonals]) = Gf nx ny L^2
// (eqs. 3-6). In the bottom layer (k = 0) there is no centre-centre bar to cut, so the
// cut dissipates (19/22) Gf nx ny L^2: a crack within half a module of a free face parallel
// to it is a geometric limit of the lattice, not of the fracture areas.
TEST(Precrack, SplitModulesDissipateGfPerUnitArea) {
  const double L = 5e-5;
  const Lattice lat(4, 3, 4, L);
  MaterialSpec m;
  m.E = 3.24e9;
  m.rho = 1190;
  m.nu = 0.25;
  m.Gf = 352.3;
  m.e_p = 0.025;
  const BarTable table(lat, m);
  for (index_t k = 0; k < 4; ++k) {
    const CutResult cut = cut_bars(lat, cross_section(lat, (k + 0.25) * L), false);
    double D = 0.0;
    for (index_t bar : cut.bars) {
      const BilinearLaw law = table.law(lat, bar);
      D += law.dissipated_energy(table.axial_stiffness(lat, bar),
                                 table.family(static_cast<int>(lat.bar_address(bar).family)).l0,
                                 {law.e_r});
    }
    const double full = m.Gf * 4 * 3 * L * L;
    const double want = k >= 1 ? full : 19.0 / 22.0 * full;
    EXPECT_NEAR(D, want, 1e-12 * full) << "k = " << k;
  }
}

// A tilted rectangle spanning the whole cross-section: z = 1.3 L + (0.4 / 6) x, which meets
// no node (corners need 1.3 + i/15 integer, centres 1.3 + (i + 1/2)/15 = m + 1/2: neither has
// an integer i in [0, 6]); the cut equals the brute-force crossing set and separates the body.
TEST(Precrack, TiltedCrossSectionSeparates) {
  const double L = 1.0;
  const Lattice lat(6, 2, 3, L);
  const Rectangle r{"tilted", {0, 0, 1.3 * L}, {6 * L, 0, 0.4 * L}, {0, 2 * L, 0}};
  const CutResult cut = cut_bars(lat, r, false);
  EXPECT_FALSE(cut.nudged);
  // Reference: sign change of the signed height above the plane, z - (1.3 + x / 15) L.
  std::vector<index_t> want;
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    const auto n = lat.bar_nodes(bar);
    const Vec3 a = lat.position(n[0]), b = lat.position(n[1]);
    const double sa = a.z - (1.3 + a.x / 15) * L, sb = b.z - (1.3 + b.x / 15) * L;
    if (sa * sb < 0)
      want.push_back(bar);
  }
  EXPECT_EQ(cut.bars, want);
  index_t count = 0;
  connected_components(lat, cut.bars, &count);
  EXPECT_EQ(count, 2u);
}

// ---------------------------------------------------------------------------------------
// Partial pre-cracks (notches)

// A notch x in [0, 2.3 L] through the full depth at z = 2.25 L of a 6 x 2 x 4 box. The
// crossing points of the layer-2 bars (bars_crossing_layer) are: vertical edges at x = i L,
// centre-centre bars at x = (i + 1/2) L, and the lower diagonals of module i, which meet the
// plane halfway between the centre ((i + 1/2) L) and the corner ((i + a) L), at
// x = (i + 1/4 + a/2) L. Inside x <= 2.3 L: edges i = 0, 1, 2 (3 x (2+1) = 9), centre-centre
// i = 0, 1 (2 x 2 = 4), diagonals of modules i = 0, 1 (4 each) and of i = 2 with a = 0 (2):
// (4 + 4 + 2) x 2 = 20. Total 33.
TEST(Precrack, NotchCutsOnlyBarsCrossingInsideIt) {
  const double L = 1.0;
  const Lattice lat(6, 2, 4, L);
  const double z0 = 2.25 * L;
  const CutResult cut = cut_bars(lat, horizontal(z0, 0, 2.3 * L, 0, 2 * L), false);
  EXPECT_EQ(cut.bars.size(), 33u);
  EXPECT_EQ(cut.bars, brute_force_horizontal(lat, z0, 0, 2.3 * L, 0, 2 * L));
  // Every cut bar crosses inside the notch; bars of the layer crossing beyond it stay intact.
  for (index_t bar : bars_crossing_layer(lat, 2)) {
    const auto n = lat.bar_nodes(bar);
    const Vec3 a = lat.position(n[0]), b = lat.position(n[1]);
    const double x = a.x + (z0 - a.z) / (b.z - a.z) * (b.x - a.x);
    EXPECT_EQ(std::binary_search(cut.bars.begin(), cut.bars.end(), bar), x <= 2.3 * L)
        << "bar " << bar << " crossing at x = " << x;
  }
  // A notch over half the cross-section does not separate the body.
  index_t count = 0;
  connected_components(lat, cut.bars, &count);
  EXPECT_EQ(count, 1u);
  const CutResult half = cut_bars(lat, horizontal(z0, 0, 3 * L, 0, 2 * L), false);
  connected_components(lat, half.bars, &count);
  EXPECT_EQ(count, 1u);
  // A notch that spans all x but only half the depth (y in [0, L]) does not either.
  const CutResult shallow = cut_bars(lat, horizontal(z0, 0, 6 * L, 0, 1 * L), false);
  connected_components(lat, shallow.bars, &count);
  EXPECT_EQ(count, 1u);
}

// SPEC 3A: 60 x 1 x 60 plate, half pre-crack 6 modules long from the symmetry plane x = 0 on
// the mid-plane z = 30 L, which is a plane of nodes: refused, then nudged to z = 30.25 L.
// Crossing points inside x in [0, 6 L], y in [0, L]: vertical edges i = 0..6, j = 0, 1 (14;
// the rectangle is closed, so x = 6 L counts), centre-centre i = 0..5 (6), lower diagonals of
// modules i = 0..5 at x = (i + 1/4) L and (i + 3/4) L (24; module 6 starts at 6.25 L): 44.
TEST(Precrack, PaperPlateHalfCrack) {
  const double L = 5e-5;
  const Lattice lat(60, 1, 60, L);
  const Rectangle r = horizontal(30 * L, 0, 6 * L, 0, L, "half_crack");
  EXPECT_TRUE(contains(refusal(lat, r, false), "plane of nodes"));
  const CutResult cut = cut_bars(lat, r, true);
  EXPECT_TRUE(cut.nudged);
  EXPECT_NEAR(cut.origin.z, 30.25 * L, 1e-12 * L);
  EXPECT_EQ(cut.bars.size(), 44u);
  EXPECT_EQ(cut.bars, brute_force_horizontal(lat, 30.25 * L, 0, 6 * L, 0, L));
  index_t count = 0;
  connected_components(lat, cut.bars, &count);
  EXPECT_EQ(count, 1u);
}

// ---------------------------------------------------------------------------------------
// connected_components on its own

TEST(ConnectedComponents, IntactIsolatedAndEmptyLattices) {
  const Lattice lat(2, 2, 2, 1.0);
  index_t count = 0;
  std::vector<index_t> label = connected_components(lat, {}, &count);
  EXPECT_EQ(count, 1u);
  for (index_t l : label)
    EXPECT_EQ(l, 0u);
  // The box corner (0, 0, 0) has exactly 4 bars: EdgeX, EdgeY, EdgeZ (0, 0, 0) and the
  // diagonal of module (0, 0, 0) to its corner (0, 0, 0), Diag0. Without them it is alone.
  std::vector<index_t> removed = {lat.bar(Family::EdgeX, 0, 0, 0), lat.bar(Family::EdgeY, 0, 0, 0),
                                  lat.bar(Family::EdgeZ, 0, 0, 0), lat.bar(Family::Diag0, 0, 0, 0)};
  std::sort(removed.begin(), removed.end());
  label = connected_components(lat, removed, &count);
  EXPECT_EQ(count, 2u);
  EXPECT_EQ(label[lat.corner(0, 0, 0)], 0u); // labels in order of first node
  for (index_t n = 1; n < lat.num_nodes(); ++n)
    EXPECT_EQ(label[n], 1u);
  // Every bar removed: every node on its own.
  std::vector<index_t> all(lat.num_bars());
  for (index_t b = 0; b < lat.num_bars(); ++b)
    all[b] = b;
  label = connected_components(lat, all, &count);
  EXPECT_EQ(count, lat.num_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    EXPECT_EQ(label[n], n);
}

} // namespace
} // namespace ldem
