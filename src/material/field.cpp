#include "material/field.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace ldem {

namespace {

double cv_of_shape(double g) {
  const double a = std::lgamma(1.0 + 2.0 / g), b = std::lgamma(1.0 + 1.0 / g);
  return std::sqrt(std::exp(a - 2.0 * b) - 1.0);
}

// SplitMix64: a bijective mixer of 64-bit words (Steele, Lea and Flood, 2014).
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

} // namespace

double weibull_shape(double cv) {
  // CV falls monotonically with the shape: from about 15.8 at g = 0.2 to 0 as g grows.
  const double g_lo = 0.2, g_hi = 1e4;
  if (!(cv > 0.0) || !(cv < cv_of_shape(g_lo)))
    throw InputError(fmt::format("Weibull field: cv = {:g} gives no Weibull shape: expected "
                                 "0 < cv < {:.4g}",
                                 cv, cv_of_shape(g_lo)));
  double lo = g_lo, hi = g_hi;
  for (int it = 0; it < 200; ++it) {
    const double mid = std::sqrt(lo * hi);
    (cv_of_shape(mid) > cv ? lo : hi) = mid;
  }
  return std::sqrt(lo * hi);
}

double weibull_scale(double mean, double shape) {
  return mean / std::tgamma(1.0 + 1.0 / shape);
}

double counter_uniform(std::uint64_t seed, std::uint64_t index) {
  const std::uint64_t r = mix(mix(seed) ^ mix(index + 0x632BE59BD9B4E019ull));
  return (static_cast<double>(r >> 11) + 0.5) * 0x1.0p-53; // in (0, 1), never 0 or 1
}

void validate_field(const Field& f, const Lattice& lat, const std::string& what) {
  const double extent = (f.axis == 0 ? lat.nx() : f.axis == 1 ? lat.ny() : lat.nz()) * lat.L();
  switch (f.kind) {
  case Field::Kind::Constant:
    return;
  case Field::Kind::Linear:
  case Field::Kind::Table: {
    if (f.table.size() < 2)
      throw InputError(fmt::format("{}: a graded field needs at least two points, got {}", what,
                                   f.table.size()));
    for (std::size_t i = 0; i < f.table.size(); ++i) {
      const double x = f.table[i].first;
      if (x < -1e-12 * lat.L() || x > extent + 1e-12 * lat.L())
        throw InputError(fmt::format("{}: grading point {:g} m lies outside the body (0 to {:g} m "
                                     "along {})",
                                     what, x, extent, static_cast<char>('x' + f.axis)));
      if (i > 0 && !(x > f.table[i - 1].first))
        throw InputError(fmt::format("{}: table coordinates must increase, got {:g} after {:g}",
                                     what, x, f.table[i - 1].first));
    }
    return;
  }
  case Field::Kind::Weibull:
    if (!(f.mean > 0.0))
      throw InputError(fmt::format("{}: Weibull mean must be positive, got {:g}", what, f.mean));
    try {
      weibull_shape(f.cv);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", what, e.what()));
    }
    return;
  }
}

std::vector<double> evaluate_field(const Field& f, const Lattice& lat) {
  const index_t nb = lat.num_bars();
  std::vector<double> v(nb, f.value);
  if (f.kind == Field::Kind::Linear || f.kind == Field::Kind::Table) {
    const auto& t = f.table;
    for (index_t b = 0; b < nb; ++b) {
      const double x = lat.bar_centre(b)[f.axis];
      // Constant beyond the first and last points; linear between neighbours.
      if (x <= t.front().first) {
        v[b] = t.front().second;
      } else if (x >= t.back().first) {
        v[b] = t.back().second;
      } else {
        const auto it = std::upper_bound(t.begin(), t.end(), x,
                                         [](double a, const auto& p) { return a < p.first; });
        const auto& [x1, y1] = *it;
        const auto& [x0, y0] = *(it - 1);
        v[b] = y0 + (y1 - y0) * (x - x0) / (x1 - x0);
      }
    }
  } else if (f.kind == Field::Kind::Weibull) {
    const double g = weibull_shape(f.cv), scale = weibull_scale(f.mean, g);
#pragma omp parallel for schedule(static) if (nb > 20000)
    for (std::int64_t b = 0; b < static_cast<std::int64_t>(nb); ++b) {
      const double u = counter_uniform(f.seed, static_cast<std::uint64_t>(b));
      v[static_cast<std::size_t>(b)] = scale * std::pow(-std::log1p(-u), 1.0 / g);
    }
  }
  return v;
}

std::string describe_field(const Field& f) {
  switch (f.kind) {
  case Field::Kind::Constant:
    return fmt::format("{:g}", f.value);
  case Field::Kind::Linear:
  case Field::Kind::Table: {
    std::string s = fmt::format("{} along {}:", f.kind == Field::Kind::Linear ? "linear" : "table",
                                static_cast<char>('x' + f.axis));
    for (const auto& [x, y] : f.table)
      s += fmt::format(" ({:g} m, {:g})", x, y);
    return s;
  }
  case Field::Kind::Weibull: {
    const double g = weibull_shape(f.cv);
    return fmt::format("Weibull: mean {:g}, cv {:g} (shape {:.4g}, scale {:.6g}), seed {}", f.mean,
                       f.cv, g, weibull_scale(f.mean, g), f.seed);
  }
  }
  return "";
}

} // namespace ldem
