#include "lattice/node_set.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cstdint>
#include <fmt/format.h>

namespace ldem {

Face parse_face(const std::string& text) {
  static const char* names[] = {"x-", "x+", "y-", "y+", "z-", "z+"};
  for (int f = 0; f < 6; ++f)
    if (text == names[f])
      return static_cast<Face>(f);
  throw InputError(fmt::format("face: expected one of x-, x+, y-, y+, z-, z+, got \"{}\"", text));
}

std::string face_name(Face f) {
  static const char* names[] = {"x-", "x+", "y-", "y+", "z-", "z+"};
  return names[static_cast<int>(f)];
}

namespace {
int axis_of(Face f) {
  return static_cast<int>(f) / 2;
}
bool is_max(Face f) {
  return static_cast<int>(f) % 2 == 1;
}
} // namespace

std::vector<index_t> select_face(const Lattice& lat, Face face) {
  const auto n = lat.modules();
  const int ax = axis_of(face);
  const index_t fixed = is_max(face) ? n[ax] : 0;
  std::vector<index_t> out;
  for (index_t k = 0; k <= n[2]; ++k)
    for (index_t j = 0; j <= n[1]; ++j)
      for (index_t i = 0; i <= n[0]; ++i) {
        const index_t idx[3] = {i, j, k};
        if (idx[ax] == fixed && lat.node_present(lat.corner(i, j, k)))
          out.push_back(lat.corner(i, j, k));
      }
  return out;
}

std::vector<double> face_tributary_areas(const Lattice& lat, Face face) {
  const auto n = lat.modules();
  const int ax = axis_of(face);
  const double quarter = 0.25 * lat.L() * lat.L();
  std::vector<double> out;
  for (index_t k = 0; k <= n[2]; ++k)
    for (index_t j = 0; j <= n[1]; ++j)
      for (index_t i = 0; i <= n[0]; ++i) {
        const index_t idx[3] = {i, j, k};
        if (idx[ax] != (is_max(face) ? n[ax] : 0))
          continue;
        // A quarter of each module face around the node: modules_sharing_edge along the two
        // axes of the face (1 on the face's border, 2 inside it).
        double a = quarter;
        if (lat.shaped()) {
          // The present modules' faces on the face among the (up to 4) around the node.
          if (!lat.node_present(lat.corner(i, j, k)))
            continue;
          const int b0 = ax == 0 ? 1 : 0, b1 = ax == 2 ? 1 : 2;
          int faces = 0;
          for (int d0 = -1; d0 <= 0; ++d0)
            for (int d1 = -1; d1 <= 0; ++d1) {
              std::int64_t m[3] = {i, j, k};
              m[ax] = is_max(face) ? n[ax] - 1 : 0;
              m[b0] += d0;
              m[b1] += d1;
              faces += m[b0] >= 0 && m[b0] < n[b0] && m[b1] >= 0 && m[b1] < n[b1] &&
                       lat.module_present(static_cast<index_t>(m[0]), static_cast<index_t>(m[1]),
                                          static_cast<index_t>(m[2]));
            }
          out.push_back(a * faces);
          continue;
        }
        for (int b = 0; b < 3; ++b)
          if (b != ax)
            a *= (idx[b] > 0) + (idx[b] < n[b]);
        out.push_back(a);
      }
  return out;
}

std::vector<double> surface_tributary_areas(const Lattice& lat,
                                            const std::vector<index_t>& nodes) {
  std::vector<double> out(nodes.size(), 0.0);
  const double quarter = 0.25 * lat.L() * lat.L();
  const index_t n[3] = {lat.nx(), lat.ny(), lat.nz()};
  // Where a node is in the set (its place), or -1.
  const auto place = [&](index_t node) -> std::ptrdiff_t {
    const auto it = std::lower_bound(nodes.begin(), nodes.end(), node);
    return it != nodes.end() && *it == node ? it - nodes.begin() : -1;
  };
  const auto present = [&](const std::int64_t m[3]) {
    for (int a = 0; a < 3; ++a)
      if (m[a] < 0 || m[a] >= n[a])
        return false;
    return lat.module_present(static_cast<index_t>(m[0]), static_cast<index_t>(m[1]),
                              static_cast<index_t>(m[2]));
  };
  for (index_t k = 0; k < n[2]; ++k)
    for (index_t j = 0; j < n[1]; ++j)
      for (index_t i = 0; i < n[0]; ++i) {
        if (!lat.module_present(i, j, k))
          continue;
        for (int ax = 0; ax < 3; ++ax) {
          if (n[ax] == 1)
            continue; // a slice's faces across its thickness
          const int b0 = ax == 0 ? 1 : 0, b1 = ax == 2 ? 1 : 2;
          for (int side = 0; side < 2; ++side) {
            std::int64_t m[3] = {i, j, k};
            m[ax] += side == 0 ? -1 : 1;
            if (present(m))
              continue;
            // The face's four corners: at index i_ax (+1 on the upper side) along ax.
            std::ptrdiff_t at[4];
            bool all = true;
            for (int c = 0; c < 4 && all; ++c) {
              index_t x[3] = {i, j, k};
              x[ax] += static_cast<index_t>(side);
              x[b0] += static_cast<index_t>(c & 1);
              x[b1] += static_cast<index_t>(c >> 1);
              at[c] = place(lat.corner(x[0], x[1], x[2]));
              all = at[c] >= 0;
            }
            if (all)
              for (const std::ptrdiff_t q : at)
                out[static_cast<std::size_t>(q)] += quarter;
          }
        }
      }
  return out;
}

std::vector<index_t> select_face_module_centres(const Lattice& lat, Face face) {
  const auto n = lat.modules();
  const int ax = axis_of(face);
  const index_t fixed = is_max(face) ? n[ax] - 1 : 0;
  std::vector<index_t> out;
  for (index_t k = 0; k < n[2]; ++k)
    for (index_t j = 0; j < n[1]; ++j)
      for (index_t i = 0; i < n[0]; ++i) {
        const index_t idx[3] = {i, j, k};
        if (idx[ax] == fixed && lat.module_present(i, j, k))
          out.push_back(lat.centre(i, j, k));
      }
  return out;
}

std::vector<index_t> select_box(const Lattice& lat, Vec3 lo, Vec3 hi) {
  const double tol = 1e-9 * lat.L();
  std::vector<index_t> out;
  for (index_t node = 0; node < lat.num_nodes(); ++node) {
    const Vec3 p = lat.position(node);
    bool inside = true;
    for (int a = 0; a < 3; ++a)
      inside = inside && p[a] >= lo[a] - tol && p[a] <= hi[a] + tol;
    if (inside && lat.node_present(node))
      out.push_back(node);
  }
  return out;
}

std::vector<index_t> select_all(const Lattice& lat) {
  std::vector<index_t> out;
  out.reserve(lat.num_present_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    if (lat.node_present(n))
      out.push_back(n);
  return out;
}

NodeSet make_node_set(std::string name, std::vector<index_t> nodes, const std::string& how) {
  if (nodes.empty())
    throw InputError(
        fmt::format("node set \"{}\" ({}) selects no node: expected at least one", name, how));
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return {std::move(name), std::move(nodes)};
}

} // namespace ldem
