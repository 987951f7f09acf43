#include "lattice/precrack.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numeric>

namespace ldem {

namespace {

Vec3 sub(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
double dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

struct Plane {
  Vec3 origin, e1, e2, n; // n unit normal
  double e1e1, e2e2;
  // Whether the projection of p onto the plane lies in the rectangle grown by `margin` (m).
  bool inside(Vec3 p, double margin = 0.0) const {
    const Vec3 r = sub(p, origin);
    const double u = dot(r, e1) / e1e1, w = dot(r, e2) / e2e2;
    const double eu = 1e-12 + margin / std::sqrt(e1e1), ew = 1e-12 + margin / std::sqrt(e2e2);
    return u >= -eu && u <= 1 + eu && w >= -ew && w <= 1 + ew;
  }
  double distance(Vec3 p) const { return dot(sub(p, origin), n); }
};

Plane make_plane(const Rectangle& r, Vec3 origin) {
  const Vec3 n = cross(r.edge1, r.edge2);
  const double nn = std::sqrt(dot(n, n));
  return {origin,
          r.edge1,
          r.edge2,
          {n.x / nn, n.y / nn, n.z / nn},
          dot(r.edge1, r.edge1),
          dot(r.edge2, r.edge2)};
}

// First node lying on the rectangle's plane (within 1e-9 L) no farther than one module from
// the rectangle, or num_nodes: a rectangle smaller than a module on a node plane separates
// nothing either.
index_t node_on_plane(const Lattice& lat, const Plane& p) {
  const double tol = 1e-9 * lat.L();
  for (index_t node = 0; node < lat.num_nodes(); ++node) {
    const Vec3 x = lat.position(node);
    if (std::abs(p.distance(x)) <= tol && p.inside(x, lat.L()))
      return node;
  }
  return lat.num_nodes();
}

} // namespace

CutResult cut_bars(const Lattice& lat, const Rectangle& rect, bool nudge) {
  const Vec3 n = cross(rect.edge1, rect.edge2);
  if (!(std::sqrt(dot(n, n)) > 1e-12 * lat.L() * lat.L()))
    throw InputError(fmt::format("pre-crack \"{}\": its two edges must span a rectangle "
                                 "(non-zero, non-parallel vectors)",
                                 rect.name));
  CutResult res;
  res.origin = rect.origin;
  Plane plane = make_plane(rect, rect.origin);
  if (index_t on = node_on_plane(lat, plane); on < lat.num_nodes()) {
    const Vec3 x = lat.position(on);
    if (!nudge)
      throw InputError(fmt::format(
          "pre-crack \"{}\" lies on a plane of nodes (node {} at ({:g}, {:g}, {:g}) m is on it): "
          "bars that only end on a surface do not cross it, so it would separate nothing; "
          "move it off the grid plane, e.g. by L/4 = {:g} m along its normal, or allow nudging",
          rect.name, on, x.x, x.y, x.z, 0.25 * lat.L()));
    const double s = 0.25 * lat.L();
    res.origin = {rect.origin.x + s * plane.n.x, rect.origin.y + s * plane.n.y,
                  rect.origin.z + s * plane.n.z};
    res.nudged = true;
    plane = make_plane(rect, res.origin);
    if (node_on_plane(lat, plane) < lat.num_nodes())
      throw InputError(fmt::format("pre-crack \"{}\": still on a plane of nodes after a "
                                   "quarter-module nudge; place it between node planes",
                                   rect.name));
  }
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    if (!lat.bar_present(bar)) // a shaped body's box outside it: nothing to cut
      continue;
    const auto [a, b] = lat.bar_nodes(bar);
    const Vec3 xa = lat.position(a), xb = lat.position(b);
    const double sa = plane.distance(xa), sb = plane.distance(xb);
    if (!(sa * sb < 0.0))
      continue;
    const double t = sa / (sa - sb);
    const Vec3 p{xa.x + t * (xb.x - xa.x), xa.y + t * (xb.y - xa.y), xa.z + t * (xb.z - xa.z)};
    if (plane.inside(p))
      res.bars.push_back(bar);
  }
  if (res.bars.empty())
    throw InputError(fmt::format("pre-crack \"{}\" crosses no bar: it lies outside the body "
                                 "(0 <= x <= {:g}, 0 <= y <= {:g}, 0 <= z <= {:g} m)",
                                 rect.name, lat.nx() * lat.L(), lat.ny() * lat.L(),
                                 lat.nz() * lat.L()));
  return res;
}

std::vector<index_t> connected_components(const Lattice& lat, const std::vector<index_t>& removed,
                                          index_t* count) {
  std::vector<index_t> parent(lat.num_nodes());
  std::iota(parent.begin(), parent.end(), index_t{0});
  auto find = [&](index_t x) {
    while (parent[x] != x)
      x = parent[x] = parent[parent[x]];
    return x;
  };
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    if (std::binary_search(removed.begin(), removed.end(), bar) || !lat.bar_present(bar))
      continue;
    const auto [a, b] = lat.bar_nodes(bar);
    const index_t ra = find(a), rb = find(b);
    if (ra != rb)
      parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  std::vector<index_t> label(lat.num_nodes());
  std::vector<index_t> root_label(lat.num_nodes(), lat.num_nodes());
  index_t next = 0;
  for (index_t node = 0; node < lat.num_nodes(); ++node) {
    const index_t r = find(node);
    if (root_label[r] == lat.num_nodes())
      root_label[r] = next++;
    label[node] = root_label[r];
  }
  if (count)
    *count = next;
  return label;
}

} // namespace ldem
