#include "lattice/lattice.hpp"

#include "util/aligned.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <limits>

namespace ldem {

std::string family_name(Family f) {
  static const char* names[kFamilies] = {"edge_x",   "edge_y", "edge_z", "centre_x", "centre_y",
                                         "centre_z", "diag_0", "diag_1", "diag_2",   "diag_3",
                                         "diag_4",   "diag_5", "diag_6", "diag_7"};
  return names[static_cast<int>(f)];
}

Lattice::Lattice(index_t nx, index_t ny, index_t nz, double L) : nx_(nx), ny_(ny), nz_(nz), L_(L) {
  if (nx == 0 || ny == 0 || nz == 0)
    throw InputError(fmt::format(
        "lattice: modules must be at least 1 in each direction, got {} x {} x {}", nx, ny, nz));
  if (!(L > 0.0) || !std::isfinite(L))
    throw InputError(fmt::format("lattice: module edge L must be a positive length, got {}", L));
  const std::uint64_t cx = nx + 1ull, cy = ny + 1ull, cz = nz + 1ull;
  const std::uint64_t modules = std::uint64_t{nx} * ny * nz;
  const std::uint64_t corners = cx * cy * cz;
  const std::uint64_t bars = std::uint64_t{nx} * cy * cz + cx * ny * cz + cx * cy * nz +
                             (nx - 1ull) * ny * nz + nx * (ny - 1ull) * nz + nx * ny * (nz - 1ull) +
                             8 * modules;
  constexpr std::uint64_t limit = std::numeric_limits<index_t>::max();
  if (corners + modules >= limit || bars >= limit)
    throw InputError(
        fmt::format("lattice: {} x {} x {} modules need {} bars, more than the {} that "
                    "32-bit indices allow on one process",
                    nx, ny, nz, bars, limit));
  num_corners_ = static_cast<index_t>(corners);
  num_centres_ = static_cast<index_t>(modules);
  num_bars_ = static_cast<index_t>(bars);

  const index_t csy = nx + 1, csz = (nx + 1) * (ny + 1); // corner strides
  const index_t msy = nx, msz = nx * ny;                 // centre strides
  const NodeMap corner_at{0, csy, csz};
  const NodeMap centre_at{num_corners_, msy, msz};
  index_t offset = 0;
  auto set = [&](Family f, index_t ni, index_t nj, index_t nk, NodeMap a, NodeMap b, Vec3 d0,
                 BarKind kind) {
    FamilyInfo& fi = families_[static_cast<int>(f)];
    fi.ni = ni;
    fi.nj = nj;
    fi.nk = nk;
    fi.offset = offset;
    fi.a = a;
    fi.b = b;
    fi.d0 = d0;
    fi.l0 = std::sqrt(d0.x * d0.x + d0.y * d0.y + d0.z * d0.z);
    fi.kind = kind;
    // A family with an empty block (centre bars of a one-module-thick direction) has no bars.
    if (ni == 0 || nj == 0 || nk == 0)
      fi.ni = fi.nj = fi.nk = 0;
    offset += fi.count();
    // Every row starts on a cache line (a multiple of 8 slots), with at least one zero slot
    // before it and after its last bar (measured: 3 % faster on 64^3, 7 % on 60 x 60 x 1).
    fi.plane_stride = static_cast<index_t>(round_up_to_line(fi.ni + 1));
    fi.plane_offset = static_cast<index_t>(round_up_to_line(plane_buffer_size_ + 1));
    plane_buffer_size_ = fi.plane_offset + fi.plane_stride * fi.nj;
  };
  set(Family::EdgeX, nx, ny + 1, nz + 1, corner_at, {1, csy, csz}, {L, 0, 0}, BarKind::Normal);
  set(Family::EdgeY, nx + 1, ny, nz + 1, corner_at, {csy, csy, csz}, {0, L, 0}, BarKind::Normal);
  set(Family::EdgeZ, nx + 1, ny + 1, nz, corner_at, {csz, csy, csz}, {0, 0, L}, BarKind::Normal);
  set(Family::CentreX, nx - 1, ny, nz, centre_at, {num_corners_ + 1, msy, msz}, {L, 0, 0},
      BarKind::Normal);
  set(Family::CentreY, nx, ny - 1, nz, centre_at, {num_corners_ + msy, msy, msz}, {0, L, 0},
      BarKind::Normal);
  set(Family::CentreZ, nx, ny, nz - 1, centre_at, {num_corners_ + msz, msy, msz}, {0, 0, L},
      BarKind::Normal);
  for (int c = 0; c < 8; ++c) {
    const index_t a = c & 1, b = (c >> 1) & 1, cc = (c >> 2) & 1;
    set(static_cast<Family>(static_cast<int>(Family::Diag0) + c), nx, ny, nz, centre_at,
        {a + b * csy + cc * csz, csy, csz}, {(a - 0.5) * L, (b - 0.5) * L, (cc - 0.5) * L},
        BarKind::Diagonal);
  }
}

NodeAddress Lattice::node_address(index_t node) const {
  if (node < num_corners_) {
    const index_t cx = nx_ + 1, cy = ny_ + 1;
    return {false, node % cx, (node / cx) % cy, node / (cx * cy)};
  }
  const index_t m = node - num_corners_;
  return {true, m % nx_, (m / nx_) % ny_, m / (nx_ * ny_)};
}

Vec3 Lattice::position(index_t node) const {
  const NodeAddress n = node_address(node);
  const double s = n.centre ? 0.5 : 0.0;
  return {(n.i + s) * L_, (n.j + s) * L_, (n.k + s) * L_};
}

int Lattice::present_in(index_t i0, index_t i1, index_t j0, index_t j1, index_t k0,
                        index_t k1) const {
  int n = 0;
  for (index_t k = k0; k != k1 + 1; ++k)
    for (index_t j = j0; j != j1 + 1; ++j)
      for (index_t i = i0; i != i1 + 1; ++i)
        n += i < nx_ && j < ny_ && k < nz_ && module_present(i, j, k);
  return n;
}

int Lattice::modules_at_corner(index_t i, index_t j, index_t k) const {
  if (present_)
    return present_in(i - 1, i, j - 1, j, k - 1, k);
  return layers_sharing(i, nx_) * layers_sharing(j, ny_) * layers_sharing(k, nz_);
}

bool Lattice::node_present(index_t node) const {
  if (!present_)
    return true;
  const NodeAddress a = node_address(node);
  return a.centre ? module_present(a.i, a.j, a.k) : modules_at_corner(a.i, a.j, a.k) > 0;
}

void Lattice::set_modules(std::shared_ptr<const std::vector<std::uint8_t>> present) {
  present_ = nullptr;
  present_count_ = {};
  if (!present)
    return;
  if (present->size() != num_modules())
    throw InputError(fmt::format("lattice: expected a mask of {} x {} x {} = {} modules, got {}",
                                 nx_, ny_, nz_, num_modules(), present->size()));
  present_ = std::move(present);
  std::uint64_t modules = 0, nodes = 0, bars = 0;
  for (std::uint8_t p : *present_)
    modules += p != 0;
  for (index_t n = 0; n < num_nodes(); ++n)
    nodes += node_present(n);
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = families_[f];
    for (index_t k = 0; k < fi.nk; ++k)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i)
          bars += area_factor(static_cast<Family>(f), i, j, k) > 0.0;
  }
  present_count_ = {modules, nodes, bars};
}

BarAddress Lattice::bar_address(index_t bar) const {
  int f = kFamilies - 1;
  while (families_[f].count() == 0 || bar < families_[f].offset)
    --f;
  const FamilyInfo& fi = families_[f];
  const index_t r = bar - fi.offset;
  return {static_cast<Family>(f), r % fi.ni, (r / fi.ni) % fi.nj, r / (fi.ni * fi.nj)};
}

std::array<index_t, 2> Lattice::bar_nodes(index_t bar) const {
  const BarAddress a = bar_address(bar);
  const FamilyInfo& fi = family(a.family);
  return {fi.a.at(a.i, a.j, a.k), fi.b.at(a.i, a.j, a.k)};
}

bool segment_meets_box(Vec3 a, Vec3 b, Vec3 lo, Vec3 hi) {
  double s0 = 0.0, s1 = 1.0; // the segment's parameters a + s (b - a) inside every slab so far
  for (int axis = 0; axis < 3; ++axis) {
    const double p = a[axis], d = b[axis] - p;
    if (d == 0.0) {
      if (p < lo[axis] || p > hi[axis])
        return false;
      continue;
    }
    double t0 = (lo[axis] - p) / d, t1 = (hi[axis] - p) / d;
    if (t0 > t1)
      std::swap(t0, t1);
    s0 = std::max(s0, t0);
    s1 = std::min(s1, t1);
    if (s0 > s1)
      return false;
  }
  return true;
}

Vec3 Lattice::bar_centre(index_t bar) const {
  const auto [a, b] = bar_nodes(bar);
  const Vec3 pa = position(a), pb = position(b);
  return {0.5 * (pa.x + pb.x), 0.5 * (pa.y + pb.y), 0.5 * (pa.z + pb.z)};
}

double Lattice::area_factor(Family f, index_t i, index_t j, index_t k) const {
  // An edge bar is shared by up to 4 modules; on the faces and edges of the box its area
  // is scaled by (modules sharing it) / 4 so that every module holds the same stiffness.
  // In a shaped body only the present modules count, so a re-entrant edge (3 modules) has 3/4.
  if (present_) {
    switch (f) {
    case Family::EdgeX:
      return 0.25 * present_in(i, i, j - 1, j, k - 1, k);
    case Family::EdgeY:
      return 0.25 * present_in(i - 1, i, j, j, k - 1, k);
    case Family::EdgeZ:
      return 0.25 * present_in(i - 1, i, j - 1, j, k, k);
    case Family::CentreX:
      return module_present(i, j, k) && module_present(i + 1, j, k) ? 1.0 : 0.0;
    case Family::CentreY:
      return module_present(i, j, k) && module_present(i, j + 1, k) ? 1.0 : 0.0;
    case Family::CentreZ:
      return module_present(i, j, k) && module_present(i, j, k + 1) ? 1.0 : 0.0;
    default:
      return module_present(i, j, k) ? 1.0 : 0.0;
    }
  }
  switch (f) {
  case Family::EdgeX:
    return 0.25 * layers_sharing(j, ny_) * layers_sharing(k, nz_);
  case Family::EdgeY:
    return 0.25 * layers_sharing(i, nx_) * layers_sharing(k, nz_);
  case Family::EdgeZ:
    return 0.25 * layers_sharing(i, nx_) * layers_sharing(j, ny_);
  default:
    return 1.0;
  }
}

double Lattice::area_factor(index_t bar) const {
  const BarAddress a = bar_address(bar);
  return area_factor(a.family, a.i, a.j, a.k);
}

std::string Lattice::describe() const {
  if (present_)
    return fmt::format("{} x {} x {} modules of L = {} m, {} of them present: {} nodes, {} bars",
                       nx_, ny_, nz_, L_, num_present_modules(), num_present_nodes(),
                       num_present_bars());
  return fmt::format("{} x {} x {} modules of L = {} m: {} nodes, {} bars", nx_, ny_, nz_, L_,
                     num_nodes(), num_bars());
}

} // namespace ldem

namespace ldem {

std::vector<NodeRow> node_rows(const Lattice& lat) {
  std::vector<NodeRow> rows;
  rows.reserve((lat.ny() + 1ull) * (lat.nz() + 1ull) + std::uint64_t{lat.ny()} * lat.nz());
  for (index_t k = 0; k <= lat.nz(); ++k)
    for (index_t j = 0; j <= lat.ny(); ++j)
      rows.push_back({false, j, k, lat.corner(0, j, k), lat.nx() + 1});
  for (index_t k = 0; k < lat.nz(); ++k)
    for (index_t j = 0; j < lat.ny(); ++j)
      rows.push_back({true, j, k, lat.centre(0, j, k), lat.nx()});
  return rows;
}

RowNumbering node_numbering(const Lattice& lat) {
  return {std::int64_t{lat.nx()} + 1, lat.nx(), lat.num_corners()};
}

int row_links(const Lattice& lat, const NodeRow& row, RowLink out[kMaxRowLinks]) {
  return row_links(lat, row, out, node_numbering(lat));
}

int row_links(const Lattice& lat, const NodeRow& row, RowLink out[kMaxRowLinks],
              const RowNumbering& num) {
  const index_t nx = lat.nx(), ny = lat.ny(), nz = lat.nz(), j = row.j, k = row.k;
  int n = 0;
  auto neg = [](Vec3 v) { return Vec3{-v.x, -v.y, -v.z}; };
  // Row node i is the first node of bar (i + shift_i, jb, kb) of family f, or its second.
  auto link = [&](Family f, index_t jb, index_t kb, index_t ilo, index_t ihi, std::int64_t shift_i,
                  std::int64_t other_first, bool first_role) {
    if (ilo >= ihi)
      return;
    const FamilyInfo& fi = lat.family(f);
    out[n++] = {std::int64_t{lat.bar(f, 0, jb, kb)} + shift_i,
                other_first,
                std::int64_t{fi.plane_offset} + std::int64_t{fi.plane_stride} * jb + shift_i,
                ilo,
                ihi,
                first_role ? fi.d0 : neg(fi.d0),
                static_cast<int>(kb) - static_cast<int>(k)};
  };
  if (!row.centre) {
    const std::int64_t c0 = num.corner(lat, j, k);
    link(Family::EdgeX, j, k, 0, nx, 0, c0 + 1, true);
    link(Family::EdgeX, j, k, 1, nx + 1, -1, c0 - 1, false);
    if (j < ny)
      link(Family::EdgeY, j, k, 0, nx + 1, 0, num.corner(lat, j + 1, k), true);
    if (j > 0)
      link(Family::EdgeY, j - 1, k, 0, nx + 1, 0, num.corner(lat, j - 1, k), false);
    if (k < nz)
      link(Family::EdgeZ, j, k, 0, nx + 1, 0, num.corner(lat, j, k + 1), true);
    if (k > 0)
      link(Family::EdgeZ, j, k - 1, 0, nx + 1, 0, num.corner(lat, j, k - 1), false);
    for (index_t c = 0; c < 8; ++c) {
      const index_t a = c & 1, b = (c >> 1) & 1, cc = (c >> 2) & 1;
      if (j < b || j - b >= ny || k < cc || k - cc >= nz)
        continue;
      // This corner is corner (a, b, cc) of module (i - a, j - b, k - cc).
      link(static_cast<Family>(static_cast<int>(Family::Diag0) + c), j - b, k - cc, a, nx + a,
           -std::int64_t{a}, num.centre(lat, j - b, k - cc) - a, false);
    }
  } else {
    const std::int64_t m0 = num.centre(lat, j, k);
    link(Family::CentreX, j, k, 0, nx - 1, 0, m0 + 1, true);
    link(Family::CentreX, j, k, 1, nx, -1, m0 - 1, false);
    if (j + 1 < ny)
      link(Family::CentreY, j, k, 0, nx, 0, num.centre(lat, j + 1, k), true);
    if (j > 0)
      link(Family::CentreY, j - 1, k, 0, nx, 0, num.centre(lat, j - 1, k), false);
    if (k + 1 < nz)
      link(Family::CentreZ, j, k, 0, nx, 0, num.centre(lat, j, k + 1), true);
    if (k > 0)
      link(Family::CentreZ, j, k - 1, 0, nx, 0, num.centre(lat, j, k - 1), false);
    for (index_t c = 0; c < 8; ++c) {
      const index_t a = c & 1, b = (c >> 1) & 1, cc = (c >> 2) & 1;
      link(static_cast<Family>(static_cast<int>(Family::Diag0) + c), j, k, 0, nx, 0,
           num.corner(lat, j + b, k + cc) + a, true);
    }
  }
  return n;
}

} // namespace ldem
