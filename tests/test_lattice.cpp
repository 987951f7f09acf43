// Tests of the cubic lattice (SPEC section 2, "Geometry" and "Masses"): node and bar
// numbering, bar families, boundary area factors, the row links the node pass gathers
// through, the lumped masses and the geometric node sets.
#include "lattice/lattice.hpp"
#include "lattice/node_set.hpp"
#include "material/bar_table.hpp"
#include "solver/simulation.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <gtest/gtest.h>
#include <omp.h>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace ldem {
namespace {

struct Box {
  index_t nx, ny, nz;
};

// Boxes with every kind of degeneracy: a single module, one-module-thick plates in each
// direction, a prism with distinct sizes and a cube with interior nodes.
const std::vector<Box> kSmallBoxes = {{1, 1, 1}, {3, 2, 4}, {2, 1, 3}, {1, 3, 2},
                                      {4, 4, 1}, {3, 3, 3}, {1, 1, 5}};

Vec3 sub(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
double norm(Vec3 a) {
  return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
}
void expect_vec_near(Vec3 got, Vec3 want, double tol, const std::string& what) {
  EXPECT_NEAR(got.x, want.x, tol) << what;
  EXPECT_NEAR(got.y, want.y, tol) << what;
  EXPECT_NEAR(got.z, want.z, tol) << what;
}

// Number of modules of the box whose closed cube [i L, (i+1) L] x ... contains p. Counts
// the modules sharing a corner node or an edge bar's midpoint without using the lattice.
int modules_containing(const Lattice& lat, Vec3 p) {
  const double tol = 1e-9 * lat.L();
  int count = 0;
  for (index_t k = 0; k < lat.nz(); ++k)
    for (index_t j = 0; j < lat.ny(); ++j)
      for (index_t i = 0; i < lat.nx(); ++i) {
        const double lo[3] = {i * lat.L(), j * lat.L(), k * lat.L()};
        bool in = true;
        for (int a = 0; a < 3; ++a)
          in = in && p[a] >= lo[a] - tol && p[a] <= lo[a] + lat.L() + tol;
        count += in ? 1 : 0;
      }
  return count;
}

bool is_edge_family(Family f) {
  return f == Family::EdgeX || f == Family::EdgeY || f == Family::EdgeZ;
}

// ---------------------------------------------------------------------------------------
// Counts

// Closed forms (SPEC section 2): corners (nx+1)(ny+1)(nz+1), centres nx ny nz; edges along
// x join corner i to i+1 (nx choices) on each of the (ny+1)(nz+1) corner lines, etc.;
// centre-centre bars along x join module i to i+1 (nx-1 choices) on each of the ny nz
// module lines, etc.; every module has 8 diagonals (one per family Diag0..Diag7).
TEST(LatticeCounts, NodesAndBarsByFamilyMatchClosedForms) {
  const std::vector<Box> boxes = {{1, 1, 1}, {3, 2, 4}, {60, 1, 60}, {5, 5, 5}, {1, 7, 2}};
  for (const Box& b : boxes) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const Lattice lat(b.nx, b.ny, b.nz, 0.5);
    const std::uint64_t nx = b.nx, ny = b.ny, nz = b.nz;
    EXPECT_EQ(lat.num_corners(), (nx + 1) * (ny + 1) * (nz + 1));
    EXPECT_EQ(lat.num_centres(), nx * ny * nz);
    EXPECT_EQ(lat.num_nodes(), (nx + 1) * (ny + 1) * (nz + 1) + nx * ny * nz);
    EXPECT_EQ(lat.num_modules(), nx * ny * nz);
    EXPECT_DOUBLE_EQ(lat.volume(), static_cast<double>(nx * ny * nz) * 0.125);

    std::array<std::uint64_t, kFamilies> want{};
    want[static_cast<int>(Family::EdgeX)] = nx * (ny + 1) * (nz + 1);
    want[static_cast<int>(Family::EdgeY)] = (nx + 1) * ny * (nz + 1);
    want[static_cast<int>(Family::EdgeZ)] = (nx + 1) * (ny + 1) * nz;
    want[static_cast<int>(Family::CentreX)] = (nx - 1) * ny * nz;
    want[static_cast<int>(Family::CentreY)] = nx * (ny - 1) * nz;
    want[static_cast<int>(Family::CentreZ)] = nx * ny * (nz - 1);
    for (int d = 0; d < 8; ++d)
      want[static_cast<int>(Family::Diag0) + d] = nx * ny * nz;

    // Families are numbered one after the other in family order.
    std::uint64_t offset = 0;
    for (int f = 0; f < kFamilies; ++f) {
      SCOPED_TRACE(family_name(static_cast<Family>(f)));
      EXPECT_EQ(lat.family(f).count(), want[f]);
      EXPECT_EQ(lat.family(f).offset, offset);
      offset += want[f];
    }
    EXPECT_EQ(lat.num_bars(), offset);
  }
}

// Per module of an n x n x n cube: edges 3 n (n+1)^2 / n^3 = 3 (1 + 1/n)^2, centre-centre
// 3 (n-1) n^2 / n^3 = 3 (1 - 1/n), diagonals 8. In total
//   bars / modules = 14 + 3/n + 3/n^2  ->  3 + 3 + 8 = 14,
// and nodes / modules = (1 + 1/n)^3 + 1 -> 2 (SPEC: "Per module in the bulk: 2 nodes,
// 3 edge bars, 3 centre-centre bars, 8 diagonals").
TEST(LatticeCounts, BulkPerModuleRatiosTendToFourteenBars) {
  double previous_excess = INFINITY;
  for (index_t n : {4u, 20u, 200u}) {
    const Lattice lat(n, n, n, 1.0);
    const double m = static_cast<double>(lat.num_modules());
    const double dn = n;
    double edges = 0, centres = 0, diags = 0;
    for (int f = 0; f < kFamilies; ++f) {
      const double c = lat.family(f).count();
      (f < 3 ? edges : (f < 6 ? centres : diags)) += c;
    }
    EXPECT_DOUBLE_EQ(edges / m, 3.0 * (1 + 1 / dn) * (1 + 1 / dn));
    EXPECT_DOUBLE_EQ(centres / m, 3.0 * (1 - 1 / dn));
    EXPECT_DOUBLE_EQ(diags / m, 8.0);
    const double excess = lat.num_bars() / m - 14.0;
    EXPECT_NEAR(excess, 3 / dn + 3 / (dn * dn), 1e-12);
    EXPECT_LT(excess, previous_excess);
    previous_excess = excess;
    EXPECT_NEAR(lat.num_nodes() / m, 2.0 + 3 / dn + 3 / (dn * dn) + 1 / (dn * dn * dn), 1e-12);
  }
  EXPECT_LT(previous_excess, 0.016); // n = 200: 3/200 + 3/40000 = 0.015075
}

TEST(LatticeCounts, RefusesEmptyBadOrOversizedBoxes) {
  EXPECT_THROW(Lattice(0, 1, 1, 1.0), InputError);
  EXPECT_THROW(Lattice(1, 0, 1, 1.0), InputError);
  EXPECT_THROW(Lattice(1, 1, 0, 1.0), InputError);
  EXPECT_THROW(Lattice(1, 1, 1, 0.0), InputError);
  EXPECT_THROW(Lattice(1, 1, 1, -1.0), InputError);
  EXPECT_THROW(Lattice(1, 1, 1, NAN), InputError);
  EXPECT_THROW(Lattice(1, 1, 1, INFINITY), InputError);
  // 2000^3 modules need about 14 x 8e9 bars, far above 2^32 - 1 = 4.29e9.
  EXPECT_THROW(Lattice(2000, 2000, 2000, 1.0), InputError);
  // 600^3: 14 x 2.16e8 + 3 x 3.6e5 + 1800 = 3.025e9 bars, below 2^32: accepted.
  EXPECT_NO_THROW(Lattice(600, 600, 600, 1.0));
}

// ---------------------------------------------------------------------------------------
// Numbering and geometry

TEST(LatticeNodes, AddressesAndPositionsRoundTrip) {
  for (const Box& b : kSmallBoxes) {
    const double L = 0.1;
    const Lattice lat(b.nx, b.ny, b.nz, L);
    std::vector<int> seen(lat.num_nodes(), 0);
    for (index_t k = 0; k <= b.nz; ++k)
      for (index_t j = 0; j <= b.ny; ++j)
        for (index_t i = 0; i <= b.nx; ++i) {
          const index_t n = lat.corner(i, j, k);
          ASSERT_LT(n, lat.num_corners());
          ++seen[n];
          const NodeAddress a = lat.node_address(n);
          EXPECT_FALSE(a.centre);
          EXPECT_FALSE(lat.is_centre(n));
          EXPECT_EQ(a.i, i);
          EXPECT_EQ(a.j, j);
          EXPECT_EQ(a.k, k);
          expect_vec_near(lat.position(n), {i * L, j * L, k * L}, 1e-12 * L, "corner");
        }
    for (index_t k = 0; k < b.nz; ++k)
      for (index_t j = 0; j < b.ny; ++j)
        for (index_t i = 0; i < b.nx; ++i) {
          const index_t n = lat.centre(i, j, k);
          ASSERT_GE(n, lat.num_corners());
          ASSERT_LT(n, lat.num_nodes());
          ++seen[n];
          const NodeAddress a = lat.node_address(n);
          EXPECT_TRUE(a.centre);
          EXPECT_TRUE(lat.is_centre(n));
          EXPECT_EQ(a.i, i);
          EXPECT_EQ(a.j, j);
          EXPECT_EQ(a.k, k);
          expect_vec_near(lat.position(n), {(i + 0.5) * L, (j + 0.5) * L, (k + 0.5) * L}, 1e-12 * L,
                          "centre");
        }
    // corner() and centre() number every node exactly once.
    for (int s : seen)
      EXPECT_EQ(s, 1);
  }
}

// modules_at_corner must count the modules whose cube has the corner as a vertex.
TEST(LatticeNodes, ModulesAtCornerCountsTouchingModules) {
  for (const Box& b : kSmallBoxes) {
    const Lattice lat(b.nx, b.ny, b.nz, 1.0);
    for (index_t k = 0; k <= b.nz; ++k)
      for (index_t j = 0; j <= b.ny; ++j)
        for (index_t i = 0; i <= b.nx; ++i)
          EXPECT_EQ(lat.modules_at_corner(i, j, k),
                    modules_containing(lat, lat.position(lat.corner(i, j, k))));
  }
}

// Every bar decodes to a family block address that encodes back to it, joins the nodes the
// family's node maps give, has the family's reference vector d0 = X_b - X_a and length L
// (edges, centre-centre) or sqrt(3)/2 L (diagonals: half a cube's space diagonal).
TEST(LatticeBars, AddressNodesAndReferenceVectorsRoundTrip) {
  for (const Box& b : kSmallBoxes) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const double L = 0.3;
    const Lattice lat(b.nx, b.ny, b.nz, L);
    for (int f = 0; f < kFamilies; ++f) {
      const FamilyInfo& fi = lat.family(f);
      const bool diag = f >= static_cast<int>(Family::Diag0);
      EXPECT_EQ(fi.kind, diag ? BarKind::Diagonal : BarKind::Normal);
      EXPECT_NEAR(fi.l0, diag ? std::sqrt(3.0) / 2.0 * L : L, 1e-15);
      EXPECT_NEAR(norm(fi.d0), fi.l0, 1e-15);
      if (diag) {
        // Diag c goes from the centre to corner (a, b, c) = bits of c: d0 = (bit - 1/2) L.
        const int c = f - static_cast<int>(Family::Diag0);
        expect_vec_near(
            fi.d0, {((c & 1) - 0.5) * L, (((c >> 1) & 1) - 0.5) * L, (((c >> 2) & 1) - 0.5) * L},
            1e-15, "diag d0");
      }
    }
    for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
      const BarAddress a = lat.bar_address(bar);
      const FamilyInfo& fi = lat.family(a.family);
      ASSERT_LT(a.i, fi.ni);
      ASSERT_LT(a.j, fi.nj);
      ASSERT_LT(a.k, fi.nk);
      EXPECT_EQ(lat.bar(a.family, a.i, a.j, a.k), bar);
      const auto nodes = lat.bar_nodes(bar);
      EXPECT_EQ(nodes[0], fi.a.at(a.i, a.j, a.k));
      EXPECT_EQ(nodes[1], fi.b.at(a.i, a.j, a.k));
      ASSERT_LT(nodes[0], lat.num_nodes());
      ASSERT_LT(nodes[1], lat.num_nodes());
      const Vec3 xa = lat.position(nodes[0]), xb = lat.position(nodes[1]);
      expect_vec_near(sub(xb, xa), fi.d0, 1e-12 * L, family_name(a.family));
      EXPECT_NEAR(norm(sub(xb, xa)), fi.l0, 1e-12 * L);
      EXPECT_EQ(lat.bar_kind(bar), fi.kind);
      expect_vec_near(lat.bar_centre(bar),
                      {(xa.x + xb.x) / 2, (xa.y + xb.y) / 2, (xa.z + xb.z) / 2}, 1e-12 * L,
                      "bar centre");
      // The first node of an edge, centre-centre or diagonal bar is a corner, a centre and a
      // centre; the second a corner, a centre and a corner.
      const bool edge = is_edge_family(a.family);
      const bool diag = fi.kind == BarKind::Diagonal;
      EXPECT_EQ(lat.is_centre(nodes[0]), !edge);
      EXPECT_EQ(lat.is_centre(nodes[1]), !edge && !diag);
    }
  }
}

// The bars, as unordered node pairs, are exactly the pairs the geometry defines (SPEC
// section 2): corner-corner and centre-centre pairs at distance L, centre-corner pairs at
// distance sqrt(3)/2 L (a centre and the 8 corners of its own module); none twice.
TEST(LatticeBars, BarSetEqualsGeometricNeighbourPairs) {
  for (const Box& b : kSmallBoxes) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const double L = 1.0;
    const Lattice lat(b.nx, b.ny, b.nz, L);
    std::set<std::pair<index_t, index_t>> want;
    for (index_t p = 0; p < lat.num_nodes(); ++p)
      for (index_t q = p + 1; q < lat.num_nodes(); ++q) {
        const double d = norm(sub(lat.position(p), lat.position(q)));
        const bool same_kind = lat.is_centre(p) == lat.is_centre(q);
        const double want_d = same_kind ? L : std::sqrt(3.0) / 2.0 * L;
        if (std::abs(d - want_d) < 1e-9)
          want.insert({p, q});
      }
    std::set<std::pair<index_t, index_t>> got;
    for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
      const auto n = lat.bar_nodes(bar);
      got.insert({std::min(n[0], n[1]), std::max(n[0], n[1])});
    }
    EXPECT_EQ(got.size(), lat.num_bars()); // no node pair twice
    EXPECT_EQ(got, want);
  }
}

// ---------------------------------------------------------------------------------------
// Boundary area factors of edge bars (SPEC: "(modules sharing it) / 4")

TEST(LatticeAreaFactor, InteriorFaceAndBoxEdgeValues) {
  const Lattice lat(3, 3, 3, 1.0);
  // EdgeX (i, j, k) runs along x at y = j, z = k.
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeX, 1, 1, 1), 1.0);  // 4 modules around it
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeX, 0, 0, 1), 0.5);  // on the face y = 0
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeX, 2, 1, 3), 0.5);  // on the face z = 3
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeX, 0, 0, 0), 0.25); // box edge y = z = 0
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeX, 2, 3, 3), 0.25); // box edge y = z = 3
  // EdgeY at x = i, z = k; EdgeZ at x = i, y = j.
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeY, 2, 0, 1), 1.0);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeY, 0, 1, 2), 0.5);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeY, 3, 1, 0), 0.25);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeZ, 1, 2, 0), 1.0);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeZ, 1, 3, 0), 0.5);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::EdgeZ, 3, 0, 2), 0.25);
  // Bars other than edges are never shared: factor 1.
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::CentreX, 0, 0, 0), 1.0);
  EXPECT_DOUBLE_EQ(lat.area_factor(Family::Diag7, 0, 0, 0), 1.0);

  // A one-module-thick plate (ny = 1): every EdgeX/EdgeZ bar lies on a y face, so it is
  // shared by at most 2 modules; the EdgeY bars cross the plate: interior ones 4 modules.
  const Lattice plate(4, 1, 4, 1.0);
  EXPECT_DOUBLE_EQ(plate.area_factor(Family::EdgeX, 1, 0, 2), 0.5);
  EXPECT_DOUBLE_EQ(plate.area_factor(Family::EdgeX, 1, 1, 0), 0.25);
  EXPECT_DOUBLE_EQ(plate.area_factor(Family::EdgeY, 2, 0, 2), 1.0);
  EXPECT_DOUBLE_EQ(plate.area_factor(Family::EdgeZ, 0, 1, 3), 0.25);
}

// area_factor of every bar equals (modules whose cube contains the bar's midpoint) / 4 for
// edges (the midpoint of an edge lies on exactly the cubes sharing the edge) and 1 otherwise.
// Summed over the edge bars: the factor of an edge is a sum of 1/4 over the modules sharing
// it, so the total is a sum of 1/4 over (module, edge of that module) pairs:
//   sum = 12 edges x 1/4 x (nx ny nz modules) = 3 nx ny nz,
// the "3 edge bars per module" of the bulk, now exact for any box.
TEST(LatticeAreaFactor, MatchesSharingModulesAndSumsToThreePerModule) {
  const std::vector<Box> boxes = {{1, 1, 1}, {3, 2, 4}, {60, 1, 60}, {5, 5, 5}, {2, 1, 3}};
  for (const Box& b : boxes) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const Lattice lat(b.nx, b.ny, b.nz, 1.0);
    const bool brute = lat.num_modules() <= 200; // cube scan is O(bars x modules)
    double sum = 0.0;
    for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
      const BarAddress a = lat.bar_address(bar);
      const double f = lat.area_factor(bar);
      EXPECT_EQ(f, lat.area_factor(a.family, a.i, a.j, a.k));
      if (!is_edge_family(a.family)) {
        EXPECT_EQ(f, 1.0);
        continue;
      }
      sum += f;
      if (brute) {
        EXPECT_EQ(f, modules_containing(lat, lat.bar_centre(bar)) / 4.0);
      }
    }
    EXPECT_DOUBLE_EQ(sum, 3.0 * b.nx * b.ny * b.nz);
  }
}

// ---------------------------------------------------------------------------------------
// Row links (lattice.hpp): what the node pass gathers must be exactly each node's bars.

TEST(LatticeRowLinks, EveryNodeGathersExactlyItsBars) {
  for (const Box& b : kSmallBoxes) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const double L = 0.7;
    const Lattice lat(b.nx, b.ny, b.nz, L);
    // Reference: scan all bars.
    std::vector<std::vector<std::pair<index_t, index_t>>> want(lat.num_nodes());
    for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
      const auto n = lat.bar_nodes(bar);
      want[n[0]].push_back({bar, n[1]});
      want[n[1]].push_back({bar, n[0]});
    }
    std::vector<std::vector<std::pair<index_t, index_t>>> got(lat.num_nodes());
    std::vector<int> node_seen(lat.num_nodes(), 0);
    std::vector<int> bar_seen(lat.num_bars(), 0);
    const std::vector<NodeRow> rows = node_rows(lat);
    EXPECT_EQ(rows.size(), (b.ny + 1) * (b.nz + 1) + b.ny * b.nz);
    for (const NodeRow& row : rows) {
      // A larger buffer than kMaxRowLinks, so that an overflow would be seen, not corrupt.
      RowLink links[2 * kMaxRowLinks];
      const int n = row_links(lat, row, links);
      ASSERT_LE(n, kMaxRowLinks);
      EXPECT_EQ(row.length, row.centre ? b.nx : b.nx + 1);
      for (index_t i = 0; i < row.length; ++i) {
        const index_t node = row.first + i;
        ASSERT_LT(node, lat.num_nodes());
        ++node_seen[node];
        const NodeAddress na = lat.node_address(node);
        EXPECT_EQ(na.centre, row.centre);
        EXPECT_EQ(na.i, i);
        EXPECT_EQ(na.j, row.j);
        EXPECT_EQ(na.k, row.k);
        for (int l = 0; l < n; ++l) {
          if (i < links[l].ilo || i >= links[l].ihi)
            continue;
          const std::int64_t bar = links[l].bar_base + i, other = links[l].other_base + i;
          ASSERT_GE(bar, 0);
          ASSERT_LT(bar, std::int64_t{lat.num_bars()});
          ASSERT_GE(other, 0);
          ASSERT_LT(other, std::int64_t{lat.num_nodes()});
          got[node].push_back({static_cast<index_t>(bar), static_cast<index_t>(other)});
          ++bar_seen[bar];
          expect_vec_near(links[l].r0,
                          sub(lat.position(static_cast<index_t>(other)), lat.position(node)),
                          1e-12 * L, "r0");
        }
      }
    }
    for (index_t node = 0; node < lat.num_nodes(); ++node) {
      EXPECT_EQ(node_seen[node], 1) << "node " << node;
      std::sort(want[node].begin(), want[node].end());
      std::sort(got[node].begin(), got[node].end());
      EXPECT_EQ(got[node], want[node]) << "node " << node;
    }
    for (index_t bar = 0; bar < lat.num_bars(); ++bar)
      EXPECT_EQ(bar_seen[bar], 2) << "bar " << bar;
  }
}

// ---------------------------------------------------------------------------------------
// Lumped masses (SPEC section 2, "Masses")

// Runs a scope on one OpenMP thread and restores the previous count. The masses do not depend
// on the thread count, and the stable-step computation a Simulation performs opens hundreds of
// tiny parallel regions that, on a machine loaded by other jobs, can spin for seconds.
class OneThread {
public:
  OneThread() : saved_(omp_get_max_threads()) { omp_set_num_threads(1); }
  ~OneThread() { omp_set_num_threads(saved_); }
  OneThread(const OneThread&) = delete;
  OneThread& operator=(const OneThread&) = delete;

private:
  int saved_;
};

Simulation make_simulation(const Box& b, double L, double rho) {
  Lattice lat(b.nx, b.ny, b.nz, L);
  MaterialSpec m;
  m.E = 3.24e9;
  m.rho = rho;
  m.nu = 0.25;
  m.Gf = 352.3;
  m.e_p = 0.025; // with L = 5e-5, K_r = 2.37 >= 1 (eq. 12), so the table is accepted
  BarTable table(lat, m);
  return Simulation(std::move(lat), std::move(table), Conditions{}, SolverOptions{});
}

// rho L^3 per module: L^3 rho / 2 at each centre node; a corner node gets rho L^3 / 2 halved
// once for every box face it lies on (f faces: rho L^3 / 2^(f+1): 1/2 inside, 1/4 on a
// face, 1/8 on a box edge, 1/16 at a box corner). Total: the corners receive 1/16 of a
// module's mass from each of the 8 corners of every module, i.e. 1/2 rho L^3 per module,
// and the centres the other half, so the sum is rho nx ny nz L^3 = rho V exactly.
TEST(LatticeMasses, LumpedMassesFollowFacesAndSumToRhoV) {
  const OneThread one_thread;
  const double L = 5e-5, rho = 1190.0, m_mod = rho * L * L * L;
  for (const Box& b : std::vector<Box>{{1, 1, 1}, {3, 3, 3}, {4, 2, 3}, {4, 1, 4}}) {
    SCOPED_TRACE(::testing::Message() << b.nx << "x" << b.ny << "x" << b.nz);
    const Simulation sim = make_simulation(b, L, rho);
    const Lattice& lat = sim.lattice();
    double total = 0.0;
    for (index_t n = 0; n < lat.num_nodes(); ++n)
      total += sim.mass(n);
    EXPECT_NEAR(total, rho * lat.volume(), 1e-12 * rho * lat.volume());
    for (index_t n = 0; n < lat.num_nodes(); ++n) {
      const NodeAddress a = lat.node_address(n);
      if (a.centre) {
        EXPECT_NEAR(sim.mass(n), m_mod / 2, 1e-14 * m_mod);
        continue;
      }
      const int faces =
          (a.i == 0 || a.i == b.nx) + (a.j == 0 || a.j == b.ny) + (a.k == 0 || a.k == b.nz);
      EXPECT_NEAR(sim.mass(n), m_mod / std::pow(2.0, faces + 1), 1e-14 * m_mod)
          << "corner (" << a.i << ", " << a.j << ", " << a.k << ")";
    }
  }
  // The four named cases on the 3 x 3 x 3 cube.
  const Simulation sim = make_simulation({3, 3, 3}, L, rho);
  const Lattice& lat = sim.lattice();
  EXPECT_NEAR(sim.mass(lat.corner(0, 0, 0)), m_mod / 16, 1e-14 * m_mod); // box corner
  EXPECT_NEAR(sim.mass(lat.corner(1, 0, 0)), m_mod / 8, 1e-14 * m_mod);  // box edge
  EXPECT_NEAR(sim.mass(lat.corner(1, 2, 0)), m_mod / 4, 1e-14 * m_mod);  // face
  EXPECT_NEAR(sim.mass(lat.corner(1, 2, 1)), m_mod / 2, 1e-14 * m_mod);  // interior
  EXPECT_NEAR(sim.mass(lat.centre(1, 1, 1)), m_mod / 2, 1e-14 * m_mod);  // centre
}

// ---------------------------------------------------------------------------------------
// Node sets

TEST(NodeSets, FaceSelectsTheCornersOnTheFace) {
  const double L = 0.1;
  const Lattice lat(3, 2, 4, L);
  const double extent[3] = {3 * L, 2 * L, 4 * L};
  const index_t n[3] = {3, 2, 4};
  for (int f = 0; f < 6; ++f) {
    const Face face = static_cast<Face>(f);
    SCOPED_TRACE(face_name(face));
    EXPECT_EQ(parse_face(face_name(face)), face);
    const int ax = f / 2;
    const double plane = f % 2 == 1 ? extent[ax] : 0.0;
    const std::vector<index_t> nodes = select_face(lat, face);
    // (n+1)(m+1) corners for a face spanned by n x m modules.
    const index_t want = (n[(ax + 1) % 3] + 1) * (n[(ax + 2) % 3] + 1);
    EXPECT_EQ(nodes.size(), want);
    EXPECT_TRUE(std::is_sorted(nodes.begin(), nodes.end()));
    EXPECT_EQ(std::set<index_t>(nodes.begin(), nodes.end()).size(), nodes.size());
    for (index_t node : nodes) {
      EXPECT_FALSE(lat.is_centre(node));
      EXPECT_NEAR(lat.position(node)[ax], plane, 1e-12);
    }
  }
  EXPECT_THROW(parse_face("top"), InputError);
}

// The centres of the module layer touching a face lie half a module inside it; a face of
// n x m modules has n m of them.
TEST(NodeSets, FaceModuleCentresAreTheFirstLayersCentres) {
  const double L = 0.1;
  const Lattice lat(3, 2, 4, L);
  const double extent[3] = {3 * L, 2 * L, 4 * L};
  const index_t n[3] = {3, 2, 4};
  for (int f = 0; f < 6; ++f) {
    const Face face = static_cast<Face>(f);
    SCOPED_TRACE(face_name(face));
    const int ax = f / 2;
    const double want_coord = f % 2 == 1 ? extent[ax] - L / 2 : L / 2;
    const std::vector<index_t> nodes = select_face_module_centres(lat, face);
    EXPECT_EQ(nodes.size(), n[(ax + 1) % 3] * n[(ax + 2) % 3]);
    EXPECT_EQ(std::set<index_t>(nodes.begin(), nodes.end()).size(), nodes.size());
    for (index_t node : nodes) {
      EXPECT_TRUE(lat.is_centre(node));
      EXPECT_NEAR(lat.position(node)[ax], want_coord, 1e-12);
    }
  }
}

TEST(NodeSets, BoxCatchesNodesOnItsFaces) {
  const double L = 0.1;
  const Lattice lat(3, 2, 4, L);
  // The closed cube of module (0, 0, 0): its 8 corners and its centre.
  std::vector<index_t> got = select_box(lat, {0, 0, 0}, {L, L, L});
  std::vector<index_t> want = {lat.corner(0, 0, 0), lat.corner(1, 0, 0), lat.corner(0, 1, 0),
                               lat.corner(1, 1, 0), lat.corner(0, 0, 1), lat.corner(1, 0, 1),
                               lat.corner(0, 1, 1), lat.corner(1, 1, 1), lat.centre(0, 0, 0)};
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, want);
  // A flat box on the bottom face, written with the decimal 0.3 (3 x 0.1 rounds to
  // 0.30000000000000004 > 0.3): the 1e-9 L tolerance must still catch the x = 3 L corners,
  // so this equals the face selection, (3+1)(2+1) = 12 corners.
  got = select_box(lat, {0, 0, 0}, {0.3, 0.2, 0.0});
  EXPECT_EQ(got.size(), 12u);
  EXPECT_EQ(got, select_face(lat, Face::ZMin));
  // The whole body.
  EXPECT_EQ(select_box(lat, {-1, -1, -1}, {1, 1, 1}), select_all(lat));
  EXPECT_EQ(select_all(lat).size(), lat.num_nodes());
  // A box between node planes selects nothing.
  EXPECT_TRUE(select_box(lat, {0.01, 0.01, 0.01}, {0.04, 0.04, 0.04}).empty());
}

TEST(NodeSets, EmptySelectionIsRefusedNamingTheSet) {
  const Lattice lat(2, 2, 2, 1.0);
  try {
    make_node_set("loaded_top", select_box(lat, {5, 5, 5}, {6, 6, 6}), "box");
    FAIL() << "an empty node set was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("loaded_top"), std::string::npos) << e.what();
  }
  // A non-empty selection is kept, sorted and without duplicates.
  const NodeSet s = make_node_set("s", {5, 1, 5, 3}, "list");
  EXPECT_EQ(s.name, "s");
  EXPECT_EQ(s.nodes, (std::vector<index_t>{1, 3, 5}));
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {
// The segment-box test that selects the bars of a fatigue box: a bar crossing a thin slab
// meets it though both its ends and its centre lie outside; one beside it, or one that ends
// short of it, does not; touching a face counts; a segment parallel to a face meets the box
// only if it lies within the slab of that axis.
TEST(SegmentMeetsBox, CrossingTouchingAndMissing) {
  const Vec3 lo{0.0, 0.0, 0.402}, hi{1.0, 1.0, 0.403};
  EXPECT_TRUE(segment_meets_box({0.5, 0.5, 0.395}, {0.5, 0.5, 0.405}, lo, hi)); // crosses
  EXPECT_TRUE(segment_meets_box({0.5, 0.5, 0.405}, {0.5, 0.5, 0.395}, lo, hi)); // reversed
  EXPECT_FALSE(segment_meets_box({0.5, 0.5, 0.40}, {0.6, 0.5, 0.40}, lo, hi)); // beside, parallel
  EXPECT_FALSE(segment_meets_box({0.5, 0.5, 0.40}, {0.5, 0.5, 0.4015}, lo, hi)); // ends short
  EXPECT_TRUE(segment_meets_box({0.5, 0.5, 0.40}, {0.5, 0.5, 0.402}, lo, hi));  // touches a face
  EXPECT_TRUE(segment_meets_box({0.2, 0.2, 0.4025}, {0.3, 0.3, 0.4025}, lo, hi)); // inside
  // A diagonal that crosses the slab's z range beside the box in x does not meet it.
  EXPECT_FALSE(segment_meets_box({1.5, 0.5, 0.40}, {2.0, 0.5, 0.41}, lo, hi));
  // One that enters the slab of z only where it has left the box in x does not either.
  EXPECT_FALSE(segment_meets_box({0.9, 0.5, 0.39}, {1.2, 0.5, 0.405}, lo, hi));
  EXPECT_TRUE(segment_meets_box({0.9, 0.5, 0.40}, {1.0, 0.5, 0.405}, lo, hi));
}
} // namespace
} // namespace ldem
