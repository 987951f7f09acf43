// Riera's cubic lattice on a box of nx x ny x nz modules of edge L.
//
// Nothing about connectivity is stored: node and bar numbers follow from the
// module indices (i, j, k) by arithmetic. Nodes are numbered corners first
// (i fastest, then j, then k), then centres in the same order. Bars come in 14
// families, each a dense 3-D block of indices (i fastest):
//   EdgeX/Y/Z      corner (i,j,k) -> next corner along x/y/z        length L
//   CentreX/Y/Z    centre (i,j,k) -> centre of the next module      length L
//   Diag0..Diag7   centre (i,j,k) -> corner (i+a, j+b, k+c),
//                  with (a,b,c) the bits of the family's number      length sqrt(3)/2 L
// A bar's first node is `a`, its second `b`; its reference vector is
// X_b - X_a, the same for every bar of a family.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace ldem {

using index_t = std::uint32_t;

struct Vec3 {
  double x = 0.0, y = 0.0, z = 0.0;
  double operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
};

// Whether the segment from a to b has a point in the box [lo, hi] (faces included): the part
// of the segment inside each slab lo <= x <= hi, intersected over the three axes.
bool segment_meets_box(Vec3 a, Vec3 b, Vec3 lo, Vec3 hi);

inline constexpr int kFamilies = 14;

enum class Family : std::uint8_t {
  EdgeX,
  EdgeY,
  EdgeZ,
  CentreX,
  CentreY,
  CentreZ,
  Diag0,
  Diag1,
  Diag2,
  Diag3,
  Diag4,
  Diag5,
  Diag6,
  Diag7
};

enum class BarKind : std::uint8_t { Normal, Diagonal };

// Node numbering inside a family's block: node(i,j,k) = base + i + j*sy + k*sz.
struct NodeMap {
  index_t base = 0, sy = 0, sz = 0;
  index_t at(index_t i, index_t j, index_t k) const { return base + i + j * sy + k * sz; }
};

struct FamilyInfo {
  index_t ni = 0, nj = 0, nk = 0; // block of bar indices
  index_t offset = 0;             // global number of the family's first bar
  // Position of the family's bar (i, j) of a k-plane in a plane buffer: plane_offset +
  // plane_stride * j + i. Rows start on cache lines (multiples of 8 slots, for a buffer that
  // starts on one) with slots to spare, so index -1 and ni of every row are zero pads (the
  // buffer's users keep them zero).
  index_t plane_offset = 0;
  index_t plane_stride = 0;
  NodeMap a, b;    // first and second node of bar (i,j,k)
  Vec3 d0;         // reference vector X_b - X_a
  double l0 = 0.0; // reference length
  BarKind kind = BarKind::Normal;
  index_t count() const { return ni * nj * nk; }
};

struct BarAddress {
  Family family;
  index_t i, j, k;
};

struct NodeAddress {
  bool centre;
  index_t i, j, k;
};

class Lattice {
public:
  // Throws InputError for non-positive sizes or a lattice too large for 32-bit indices.
  Lattice(index_t nx, index_t ny, index_t nz, double L);

  index_t nx() const { return nx_; }
  index_t ny() const { return ny_; }
  index_t nz() const { return nz_; }
  double L() const { return L_; }
  std::array<index_t, 3> modules() const { return {nx_, ny_, nz_}; }
  std::uint64_t num_modules() const { return std::uint64_t{nx_} * ny_ * nz_; }
  // The volume of the body: its present modules'.
  double volume() const { return static_cast<double>(num_present_modules()) * L_ * L_ * L_; }

  // A body that is not the full box (lattice/shape.hpp): one byte per module of the box, i
  // fastest (i + nx (j + ny k)), nonzero where the module is present. Nodes and bars keep the
  // box's numbering; a node is present when a present module has it, a bar when its area
  // factor is not zero (an edge bar: some present module shares it; a centre bar: both its
  // modules are present; a diagonal: its module is). Throws InputError for a mask of the wrong
  // size. (A window of a distributed run may hold no present module.)
  void set_modules(std::shared_ptr<const std::vector<std::uint8_t>> present);
  bool shaped() const { return present_ != nullptr; }
  const std::shared_ptr<const std::vector<std::uint8_t>>& modules_present() const {
    return present_;
  }
  bool module_present(index_t i, index_t j, index_t k) const {
    return !present_ || (*present_)[i + std::size_t{nx_} * (j + std::size_t{ny_} * k)] != 0;
  }
  bool node_present(index_t node) const;
  bool bar_present(index_t bar) const { return !present_ || area_factor(bar) > 0.0; }
  std::uint64_t num_present_modules() const { return present_ ? present_count_[0] : num_modules(); }
  std::uint64_t num_present_nodes() const { return present_ ? present_count_[1] : num_nodes(); }
  std::uint64_t num_present_bars() const { return present_ ? present_count_[2] : num_bars(); }

  index_t num_corners() const { return num_corners_; }
  index_t num_centres() const { return num_centres_; }
  index_t num_nodes() const { return num_corners_ + num_centres_; }
  index_t num_bars() const { return num_bars_; }
  // Size of a buffer holding one value per bar of a k-plane, family after family, i fastest,
  // with a zero pad around every row (FamilyInfo::plane_offset, plane_stride).
  index_t plane_buffer_size() const { return plane_buffer_size_; }

  index_t corner(index_t i, index_t j, index_t k) const {
    return i + (nx_ + 1) * (j + (ny_ + 1) * k);
  }
  index_t centre(index_t i, index_t j, index_t k) const {
    return num_corners_ + i + nx_ * (j + ny_ * k);
  }
  NodeAddress node_address(index_t node) const;
  Vec3 position(index_t node) const;
  bool is_centre(index_t node) const { return node >= num_corners_; }
  // Number of present modules (0..8) that share a corner node.
  int modules_at_corner(index_t i, index_t j, index_t k) const;

  const FamilyInfo& family(Family f) const { return families_[static_cast<int>(f)]; }
  const FamilyInfo& family(int f) const { return families_[f]; }
  index_t bar(Family f, index_t i, index_t j, index_t k) const {
    const FamilyInfo& fi = family(f);
    return fi.offset + i + fi.ni * (j + fi.nj * k);
  }
  BarAddress bar_address(index_t bar) const;
  std::array<index_t, 2> bar_nodes(index_t bar) const;
  Vec3 bar_centre(index_t bar) const;
  BarKind bar_kind(index_t bar) const { return family(bar_address(bar).family).kind; }
  // Boundary scaling of an edge bar: (present modules sharing it) / 4; for other bars 1, or 0
  // where a module they need is absent.
  double area_factor(index_t bar) const;
  double area_factor(Family f, index_t i, index_t j, index_t k) const;

  std::string describe() const;

private:
  index_t nx_, ny_, nz_;
  double L_;
  index_t num_corners_ = 0, num_centres_ = 0, num_bars_ = 0, plane_buffer_size_ = 0;
  std::array<FamilyInfo, kFamilies> families_{};
  std::shared_ptr<const std::vector<std::uint8_t>> present_;
  std::array<std::uint64_t, 3> present_count_{}; // modules, nodes, bars
  // Present modules among those of [i0, i1] x [j0, j1] x [k0, k1] inside the box (indices may
  // run one below 0, as index_t(-1), or to n, outside it).
  int present_in(index_t i0, index_t i1, index_t j0, index_t j1, index_t k0, index_t k1) const;
};

// Number of modules sharing an edge bar along one axis, from the transverse indices
// of the edge: an index on the box boundary is shared by one module layer, else two.
inline int layers_sharing(index_t idx, index_t n) {
  return (idx > 0 ? 1 : 0) + (idx < n ? 1 : 0);
}

std::string family_name(Family f);

} // namespace ldem

namespace ldem {

// A numbering of the nodes row by row, i counting along each row: corner row (j, k) starts at
// corner_row * (j + (ny + 1) k), centre row (j, k) at centre_first + centre_row * (j + ny k).
// The lattice's own numbering has rows nx + 1 and nx long, centres after the last corner; the
// step loop's arrays leave room after each row (Simulation's node slots).
struct RowNumbering {
  std::int64_t corner_row = 0, centre_row = 0, centre_first = 0;
  std::int64_t corner(const Lattice& lat, index_t j, index_t k) const {
    return corner_row * (j + (std::int64_t{lat.ny()} + 1) * k);
  }
  std::int64_t centre(const Lattice& lat, index_t j, index_t k) const {
    return centre_first + centre_row * (j + std::int64_t{lat.ny()} * k);
  }
};
RowNumbering node_numbering(const Lattice& lattice);

// The bars that meet the nodes of one row of nodes (fixed j, k; i running), as up to 14
// links, each covering a range of i. For node i of the row, link `l` with
// l.ilo <= i < l.ihi joins bar l.bar_base + i to node l.other_base + i (in the numbering
// row_links is given; the lattice's by default), and the reference vector from the row's node
// to that other node is l.r0. The order is fixed (family order, first-node role before
// second-node role), so a sum over links is deterministic.
struct RowLink {
  std::int64_t bar_base, other_base, plane_base;
  index_t ilo, ihi;
  Vec3 r0;
  int dk;
};
inline constexpr int kMaxRowLinks = 14;

struct NodeRow {
  bool centre;
  index_t j, k;
  index_t first;  // node number of i = 0
  index_t length; // nx + 1 corners or nx centres
};

// Every row of nodes: corner rows first (k outer, j inner), then centre rows.
std::vector<NodeRow> node_rows(const Lattice& lattice);
int row_links(const Lattice& lattice, const NodeRow& row, RowLink out[kMaxRowLinks]);
int row_links(const Lattice& lattice, const NodeRow& row, RowLink out[kMaxRowLinks],
              const RowNumbering& numbering);

} // namespace ldem
