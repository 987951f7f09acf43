#include "lattice/shape.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>

namespace ldem {

namespace {

double dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
Vec3 minus(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}

// p turned by `angle` about the axis `axis` through c.
Vec3 turned(Vec3 p, Vec3 c, int axis, double angle) {
  const Vec3 d = minus(p, c);
  const double cs = std::cos(angle), sn = std::sin(angle);
  Vec3 r = d;
  if (axis == 0)
    r = {d.x, cs * d.y - sn * d.z, sn * d.y + cs * d.z};
  else if (axis == 1)
    r = {cs * d.x + sn * d.z, d.y, -sn * d.x + cs * d.z};
  else if (axis == 2)
    r = {cs * d.x - sn * d.y, sn * d.x + cs * d.y, d.z};
  return {c.x + r.x, c.y + r.y, c.z + r.z};
}

} // namespace

bool Shape::contains(Vec3 p, double tol) const {
  switch (type) {
  case Type::Box: {
    const Vec3 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
    const Vec3 q = axis < 0 ? p : turned(p, c, axis, -angle); // back into the box's frame
    return q.x >= lo.x - tol && q.x <= hi.x + tol && q.y >= lo.y - tol && q.y <= hi.y + tol &&
           q.z >= lo.z - tol && q.z <= hi.z + tol;
  }
  case Type::Cylinder: {
    const Vec3 d = minus(b, a), r = minus(p, a);
    const double len = std::sqrt(dot(d, d)), t = dot(r, d) / (len * len);
    if (t < -tol / len || t > 1.0 + tol / len)
      return false;
    const Vec3 off{r.x - t * d.x, r.y - t * d.y, r.z - t * d.z};
    return dot(off, off) <= (radius + tol) * (radius + tol);
  }
  case Type::Sphere: {
    const Vec3 r = minus(p, a);
    return dot(r, r) <= (radius + tol) * (radius + tol);
  }
  case Type::HalfSpace:
    return dot(minus(p, a), normal) >= -tol * std::sqrt(dot(normal, normal));
  case Type::Mask:
    break;
  }
  return false;
}

std::string Shape::describe() const {
  auto v = [](Vec3 q) { return fmt::format("[{:g}, {:g}, {:g}]", q.x, q.y, q.z); };
  switch (type) {
  case Type::Box:
    return axis < 0 ? fmt::format("box {} to {}", v(lo), v(hi))
                    : fmt::format("box {} to {} turned by {:g} degrees about {}", v(lo), v(hi),
                                  angle * 180.0 / std::numbers::pi, "xyz"[axis]);
  case Type::Cylinder:
    return fmt::format("cylinder of radius {:g} m from {} to {}", radius, v(a), v(b));
  case Type::Sphere:
    return fmt::format("sphere of radius {:g} m about {}", radius, v(a));
  case Type::HalfSpace:
    return fmt::format("half-space through {} towards {}", v(a), v(normal));
  case Type::Mask:
    break;
  }
  return "mask";
}

std::vector<index_t> select_shape(const Lattice& lat, const Shape& shape) {
  const double tol = 1e-9 * lat.L();
  std::vector<index_t> out;
  for (index_t node = 0; node < lat.num_nodes(); ++node)
    if (lat.node_present(node) && shape.contains(lat.position(node), tol))
      out.push_back(node);
  return out;
}

std::vector<index_t> select_surface(const Lattice& lat, const Shape& shape) {
  const double tol = 1e-9 * lat.L();
  std::vector<index_t> out;
  for (index_t k = 0; k <= lat.nz(); ++k)
    for (index_t j = 0; j <= lat.ny(); ++j)
      for (index_t i = 0; i <= lat.nx(); ++i) {
        // The 8 modules around the corner; beyond the box they are absent, except across a
        // direction in which the body is one module thick (a slice of a longer body: plane
        // strain or stress), where they are the slice's own.
        const index_t at[3] = {i, j, k}, n[3] = {lat.nx(), lat.ny(), lat.nz()};
        int present = 0, absent = 0;
        for (int c = 0; c < 8; ++c) {
          index_t m[3];
          bool outside = false;
          for (int a = 0; a < 3; ++a) {
            const bool below = ((c >> a) & 1) == 0;
            if (below && at[a] == 0) {
              outside |= n[a] > 1;
              m[a] = 0;
            } else if (!below && at[a] == n[a]) {
              outside |= n[a] > 1;
              m[a] = n[a] - 1;
            } else {
              m[a] = below ? at[a] - 1 : at[a];
            }
          }
          if (!outside && lat.module_present(m[0], m[1], m[2]))
            ++present;
          else
            ++absent;
        }
        const index_t node = lat.corner(i, j, k);
        if (present > 0 && absent > 0 && shape.contains(lat.position(node), tol))
          out.push_back(node);
      }
  return out;
}

ModuleMask build_module_mask(index_t nx, index_t ny, index_t nz, double L,
                             const std::vector<ShapeOp>& ops) {
  ModuleMask m;
  m.nx = nx;
  m.ny = ny;
  m.nz = nz;
  const std::size_t n = std::size_t{nx} * ny * nz;
  m.present.assign(n, ops.empty() || !ops.front().add ? 1 : 0);
  for (const ShapeOp& op : ops) {
    const std::uint8_t value = op.add ? 1 : 0;
    if (op.shape.type == Shape::Type::Mask) {
      const std::vector<std::uint8_t>& mask = *op.shape.mask;
      for (std::size_t q = 0; q < n; ++q)
        if (mask[q])
          m.present[q] = value;
      continue;
    }
    for (index_t k = 0; k < nz; ++k)
      for (index_t j = 0; j < ny; ++j)
        for (index_t i = 0; i < nx; ++i)
          if (op.shape.contains({(i + 0.5) * L, (j + 0.5) * L, (k + 0.5) * L}, 1e-9 * L))
            m.present[i + std::size_t{nx} * (j + std::size_t{ny} * k)] = value;
  }

  // Pieces: modules joined through faces (breadth-first, in module order).
  constexpr std::uint32_t none = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> piece(n, none);
  std::vector<std::uint64_t> size;
  std::vector<std::size_t> queue;
  const std::size_t sy = nx, sz = std::size_t{nx} * ny;
  for (std::size_t s = 0; s < n; ++s) {
    if (!m.present[s] || piece[s] != none)
      continue;
    const auto p = static_cast<std::uint32_t>(size.size());
    size.push_back(0);
    queue.assign(1, s);
    piece[s] = p;
    while (!queue.empty()) {
      const std::size_t q = queue.back();
      queue.pop_back();
      ++size[p];
      const std::size_t i = q % sy, j = (q / sy) % ny, k = q / sz;
      auto visit = [&](bool inside, std::size_t r) {
        if (inside && m.present[r] && piece[r] == none) {
          piece[r] = p;
          queue.push_back(r);
        }
      };
      visit(i > 0, q - 1);
      visit(i + 1 < nx, q + 1);
      visit(j > 0, q - sy);
      visit(j + 1 < ny, q + sy);
      visit(k > 0, q - sz);
      visit(k + 1 < nz, q + sz);
    }
  }

  // The largest piece is kept; each other piece, from the larger to the smaller (the earlier
  // in module order among equals), is removed if it meets a kept piece at an edge or a corner,
  // and kept otherwise. The modules of each piece, in module order.
  const std::size_t pieces = size.size();
  std::vector<std::size_t> start(pieces + 1, 0), modules(n);
  for (std::size_t s = 0; s < n; ++s)
    if (piece[s] != none)
      ++start[piece[s] + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t s = 0; s < n; ++s)
      if (piece[s] != none)
        modules[fill[piece[s]]++] = s;
  }
  std::vector<std::uint32_t> order(pieces);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return size[a] > size[b]; });
  std::vector<std::uint8_t> kept(pieces, 0);
  for (const std::uint32_t p : order) {
    bool hinge = false;
    for (std::size_t q = start[p]; q < start[p + 1] && !hinge; ++q) {
      const std::size_t s = modules[q];
      const auto i = static_cast<std::int64_t>(s % sy),
                 j = static_cast<std::int64_t>((s / sy) % ny),
                 k = static_cast<std::int64_t>(s / sz);
      for (int dk = -1; dk <= 1 && !hinge; ++dk)
        for (int dj = -1; dj <= 1 && !hinge; ++dj)
          for (int di = -1; di <= 1 && !hinge; ++di) {
            if ((di != 0) + (dj != 0) + (dk != 0) < 2) // itself and its face neighbours
              continue;
            const std::int64_t a = i + di, b = j + dj, c = k + dk;
            if (a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz)
              continue;
            const std::size_t r = static_cast<std::size_t>(a) + sy * static_cast<std::size_t>(b) +
                                  sz * static_cast<std::size_t>(c);
            hinge = piece[r] != none && piece[r] != p && kept[piece[r]];
          }
    }
    if (hinge) {
      m.hinged += size[p];
      for (std::size_t q = start[p]; q < start[p + 1]; ++q)
        m.present[modules[q]] = 0;
    } else {
      kept[p] = 1;
      ++m.pieces;
      m.count += size[p];
    }
  }
  if (m.count == 0)
    throw InputError(fmt::format("shape: expected operations that leave modules of the "
                                 "{} x {} x {} grid in the body, got none left",
                                 nx, ny, nz));
  return m;
}

namespace {

// The value of `key` in a .npy header's dictionary, as its text up to the next top-level
// comma or the closing brace.
std::string header_value(const std::string& header, const std::string& key) {
  const std::size_t at = header.find("'" + key + "'");
  if (at == std::string::npos)
    return {};
  std::size_t p = header.find(':', at);
  if (p == std::string::npos)
    return {};
  ++p;
  int depth = 0;
  std::string v;
  for (; p < header.size(); ++p) {
    const char c = header[p];
    if (c == '(')
      ++depth;
    if (c == ')')
      --depth;
    if (depth == 0 && (c == ',' || c == '}'))
      break;
    v += c;
  }
  const auto b = v.find_first_not_of(" \t"), e = v.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : v.substr(b, e - b + 1);
}

} // namespace

namespace {

// The bytes of a file a case names (`what`: "mask", "STL"); a path that is not a regular file
// or cannot be opened is an InputError naming it.
std::string read_input_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw InputError(fmt::format("{}: expected {} {} file, got something else (a folder, a "
                                 "device)",
                                 path, what == "STL" ? "an" : "a", what));
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(fmt::format("{}: cannot open the {} file", path, what));
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

} // namespace

std::vector<std::uint8_t> read_npy_mask(const std::string& path, index_t nx, index_t ny,
                                        index_t nz) {
  const std::string bytes = read_input_file(path, "mask");
  auto fail = [&](const std::string& what) -> std::vector<std::uint8_t> {
    throw InputError(fmt::format("{}: {}", path, what));
  };
  if (bytes.size() < 10 || std::memcmp(bytes.data(), "\x93NUMPY", 6) != 0)
    return fail("expected a NumPy .npy file (numpy.save), got a file without its signature");
  const auto major = static_cast<unsigned char>(bytes[6]);
  std::size_t header_len = 0, header_at = 0;
  auto byte = [&](std::size_t q) {
    return static_cast<std::size_t>(static_cast<unsigned char>(bytes[q]));
  };
  if (major == 1) {
    header_len = byte(8) | byte(9) << 8;
    header_at = 10;
  } else if ((major == 2 || major == 3) && bytes.size() >= 12) {
    header_len = byte(8) | byte(9) << 8 | byte(10) << 16 | byte(11) << 24;
    header_at = 12;
  } else {
    return fail(fmt::format("expected .npy format version 1, 2 or 3, got {}", major));
  }
  if (bytes.size() < header_at + header_len)
    return fail("expected a whole .npy header, got a file cut short");
  const std::string header(bytes.data() + header_at, header_len);
  std::string descr = header_value(header, "descr");
  const std::string order = header_value(header, "fortran_order");
  const std::string shape = header_value(header, "shape");
  if (descr.size() < 4 || (descr.front() != '\'' && descr.front() != '"'))
    return fail(fmt::format("expected a plain array type in the header, got descr {}", descr));
  descr = descr.substr(1, descr.size() - 2);
  const char endian = descr[0], kind = descr[1];
  const int item = std::atoi(descr.c_str() + 2);
  const bool known_size =
      kind == 'f' ? (item == 4 || item == 8) : (item == 1 || item == 2 || item == 4 || item == 8);
  if ((kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f') || !known_size ||
      (kind == 'b' && item != 1))
    return fail(
        fmt::format("expected an array of booleans, integers or floats, got type '{}'", descr));
  if (endian == '>' && item > 1)
    return fail(fmt::format("expected little-endian values, got type '{}' (big-endian)", descr));
  if (order != "False" && order != "True")
    return fail(fmt::format("expected fortran_order True or False, got {}", order));
  const bool fortran = order == "True";
  std::vector<std::uint64_t> dims;
  for (std::size_t p = 0; p < shape.size();) {
    if (std::isdigit(static_cast<unsigned char>(shape[p]))) {
      std::size_t used = 0;
      dims.push_back(std::stoull(shape.substr(p), &used));
      p += used;
    } else {
      ++p;
    }
  }
  if (dims != std::vector<std::uint64_t>{nx, ny, nz})
    return fail(fmt::format("expected an array of shape ({}, {}, {}), one value per module "
                            "[i, j, k], got shape {}",
                            nx, ny, nz, shape));
  const std::size_t n = std::size_t{nx} * ny * nz, data_at = header_at + header_len;
  if (bytes.size() < data_at + n * static_cast<std::size_t>(item))
    return fail(fmt::format("expected {} values of {} bytes after the header, got {} bytes", n,
                            item, bytes.size() - data_at));
  std::vector<std::uint8_t> out(n);
  const char* data = bytes.data() + data_at;
  for (index_t k = 0; k < nz; ++k)
    for (index_t j = 0; j < ny; ++j)
      for (index_t i = 0; i < nx; ++i) {
        const std::size_t q = fortran ? i + std::size_t{nx} * (j + std::size_t{ny} * k)
                                      : k + std::size_t{nz} * (j + std::size_t{ny} * i);
        const char* v = data + q * static_cast<std::size_t>(item);
        bool on = false;
        if (kind == 'f') {
          double x = 0.0;
          if (item == 4) {
            float f;
            std::memcpy(&f, v, 4);
            x = f;
          } else {
            std::memcpy(&x, v, 8);
          }
          if (std::isnan(x))
            fail(fmt::format("expected numbers, got NaN at [{}, {}, {}]", i, j, k));
          on = x != 0.0;
        } else {
          for (int b = 0; b < item; ++b)
            on = on || v[b] != 0;
        }
        out[i + std::size_t{nx} * (j + std::size_t{ny} * k)] = on ? 1 : 0;
      }
  return out;
}

std::vector<Triangle> read_stl(const std::string& path, double scale) {
  const std::string bytes = read_input_file(path, "STL");
  std::vector<Triangle> out;
  auto finite = [&](const Triangle& t) {
    for (const Vec3& v : t)
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
        throw InputError(
            fmt::format("{}: triangle {} has a vertex that is not a number", path, out.size()));
  };
  // Binary: an 80-byte header, a uint32 count, 50 bytes per triangle (normal, 3 vertices as
  // float32, a uint16). Taken as binary when the size matches its count, whatever the header
  // says (binary files often begin with "solid" too).
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (bytes.size() == 84 + 50ull * n) {
      out.reserve(n);
      for (std::uint32_t t = 0; t < n; ++t) {
        const char* p = bytes.data() + 84 + 50ull * t + 12;
        Triangle tri;
        for (int v = 0; v < 3; ++v) {
          float c[3];
          std::memcpy(c, p + 12 * v, 12);
          tri[static_cast<std::size_t>(v)] = {c[0] * scale, c[1] * scale, c[2] * scale};
        }
        finite(tri);
        out.push_back(tri);
      }
      if (out.empty())
        throw InputError(fmt::format("{}: the STL file holds no triangle", path));
      return out;
    }
  }
  // ASCII: "vertex x y z" lines, three per facet.
  if (bytes.compare(0, 5, "solid") != 0)
    throw InputError(fmt::format("{}: expected an STL file (binary, or ASCII beginning with "
                                 "\"solid\"), got neither",
                                 path));
  std::istringstream text(bytes);
  std::string word;
  Triangle tri;
  int v = 0;
  while (text >> word) {
    if (word != "vertex")
      continue;
    double x, y, z;
    if (!(text >> x >> y >> z))
      throw InputError(
          fmt::format("{}: a vertex of facet {} is not three numbers", path, out.size()));
    tri[static_cast<std::size_t>(v)] = {x * scale, y * scale, z * scale};
    if (++v == 3) {
      finite(tri);
      out.push_back(tri);
      v = 0;
    }
  }
  if (v != 0)
    throw InputError(fmt::format("{}: the last facet has {} vertices, expected 3", path, v));
  if (out.empty())
    throw InputError(fmt::format("{}: the STL file holds no triangle", path));
  return out;
}

std::vector<std::uint8_t> surface_mask(const std::vector<Triangle>& triangles, index_t nx,
                                       index_t ny, index_t nz, double L, const std::string& what) {
  // The rows' lines: y = (j + 1/2 + dy) L, z = (k + 1/2 + dz) L, off the centres by amounts no
  // mesh on a grid of round numbers meets exactly.
  const double dy = 1.234567e-7, dz = 2.718281e-7;
  std::vector<std::vector<std::uint32_t>> bins(std::size_t{ny} * nz);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Triangle& tr = triangles[t];
    const double y0 = std::min({tr[0].y, tr[1].y, tr[2].y}),
                 y1 = std::max({tr[0].y, tr[1].y, tr[2].y});
    const double z0 = std::min({tr[0].z, tr[1].z, tr[2].z}),
                 z1 = std::max({tr[0].z, tr[1].z, tr[2].z});
    // Rows whose line may meet the triangle's box.
    const auto first = [](double lo, index_t n) {
      return static_cast<index_t>(std::clamp(std::floor(lo - 0.5), 0.0, static_cast<double>(n)));
    };
    const auto last = [](double hi, index_t n) {
      return static_cast<index_t>(std::clamp(std::ceil(hi - 0.5), 0.0, static_cast<double>(n)));
    };
    for (index_t k = first(z0 / L, nz); k < std::min(last(z1 / L, nz) + 1, nz); ++k)
      for (index_t j = first(y0 / L, ny); j < std::min(last(y1 / L, ny) + 1, ny); ++j)
        bins[j + std::size_t{ny} * k].push_back(static_cast<std::uint32_t>(t));
  }
  std::vector<std::uint8_t> mask(std::size_t{nx} * ny * nz, 0);
  std::vector<double> xs;
  for (index_t k = 0; k < nz; ++k)
    for (index_t j = 0; j < ny; ++j) {
      const double y = (j + 0.5 + dy) * L, z = (k + 0.5 + dz) * L;
      xs.clear();
      for (const std::uint32_t t : bins[j + std::size_t{ny} * k]) {
        const Triangle& tr = triangles[t];
        // Barycentric coordinates of (y, z) in the triangle's projection on the y-z plane.
        const double ay = tr[0].y, az = tr[0].z;
        const double by = tr[1].y - ay, bz = tr[1].z - az, cy = tr[2].y - ay, cz = tr[2].z - az;
        const double det = by * cz - bz * cy;
        if (det == 0.0)
          continue; // the triangle is edge-on to the line: it holds no crossing
        const double py = y - ay, pz = z - az;
        const double u = (py * cz - pz * cy) / det, w = (by * pz - bz * py) / det;
        if (u < 0.0 || w < 0.0 || u + w > 1.0)
          continue;
        xs.push_back(tr[0].x + u * (tr[1].x - tr[0].x) + w * (tr[2].x - tr[0].x));
      }
      if (xs.size() % 2 != 0)
        throw InputError(fmt::format(
            "{}: expected a closed surface, got one that the line along x through the centres "
            "of module row (j, k) = ({}, {}) crosses {} times (an odd number: a hole in the "
            "surface, or facets missing or doubled)",
            what, j, k, xs.size()));
      std::sort(xs.begin(), xs.end());
      std::size_t before = 0;
      for (index_t i = 0; i < nx; ++i) {
        const double x = (i + 0.5) * L;
        while (before < xs.size() && xs[before] < x)
          ++before;
        mask[i + std::size_t{nx} * (j + std::size_t{ny} * k)] = before % 2;
      }
    }
  return mask;
}

} // namespace ldem
