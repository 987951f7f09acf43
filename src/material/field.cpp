#include "material/field.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <fftw3.h>
#include <fmt/format.h>
#include <numbers>

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
    if (f.correlation_length < 0.0 || !std::isfinite(f.correlation_length))
      throw InputError(fmt::format("{}: correlation_length must be >= 0 m, got {:g}", what,
                                   f.correlation_length));
    if (f.correlation_length > 0.0) {
      const double cells = (lat.nx() * lat.L() / f.correlation_length * 8.0 + 25.0) *
                           (lat.ny() * lat.L() / f.correlation_length * 8.0 + 25.0) *
                           (lat.nz() * lat.L() / f.correlation_length * 8.0 + 25.0);
      if (cells > 2e8)
        throw InputError(fmt::format("{}: correlation_length {:g} m needs a grid of {:.3g} "
                                     "points for this body; the limit is 2e8 (use a longer "
                                     "correlation length)",
                                     what, f.correlation_length, cells));
    }
    try {
      weibull_shape(f.cv);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", what, e.what()));
    }
    return;
  }
}

namespace {

// The field at n points: position(i) gives point i, and id(i) numbers its random draw.
template <class Position, class Id>
std::vector<double> evaluate_at(const Field& f, const Lattice& lat, index_t nb, Position&& position,
                                Id&& id, std::uint64_t stream) {
  std::vector<double> v(nb, f.value);
  if (f.kind == Field::Kind::Linear || f.kind == Field::Kind::Table) {
    const auto& t = f.table;
    for (index_t b = 0; b < nb; ++b) {
      const double x = position(b)[f.axis];
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
  } else if (f.kind == Field::Kind::Weibull && f.correlation_length > 0.0) {
    const double g = weibull_shape(f.cv), scale = weibull_scale(f.mean, g);
    std::vector<Vec3> points(nb);
    for (index_t b = 0; b < nb; ++b)
      points[b] = position(b);
    v = correlated_gaussian(lat, points, f.correlation_length, f.covariance, f.seed);
    for (double& x : v) {
      const double u = std::clamp(0.5 * std::erfc(-x / std::numbers::sqrt2), 1e-300, 1.0 - 1e-16);
      x = scale * std::pow(-std::log1p(-u), 1.0 / g);
    }
  } else if (f.kind == Field::Kind::Weibull) {
    const double g = weibull_shape(f.cv), scale = weibull_scale(f.mean, g);
#pragma omp parallel for schedule(static) if (nb > 20000)
    for (std::int64_t b = 0; b < static_cast<std::int64_t>(nb); ++b) {
      const double u = counter_uniform(f.seed ^ stream, id(static_cast<index_t>(b)));
      v[static_cast<std::size_t>(b)] = scale * std::pow(-std::log1p(-u), 1.0 / g);
    }
  }
  return v;
}

} // namespace

namespace {
// Module draws use their own stream, so that a density field is not the toughness field.
constexpr std::uint64_t kModuleStream = 0x5DEECE66Dull;
std::uint64_t same(index_t b) {
  return b;
}
} // namespace

std::vector<double> evaluate_field(const Field& f, const Lattice& lat) {
  return evaluate_at(
      f, lat, lat.num_bars(), [&](index_t b) { return lat.bar_centre(b); }, same, 0);
}

std::vector<double> evaluate_field(const Field& f, const Lattice& lat,
                                   const std::vector<index_t>& bars) {
  return evaluate_at(
      f, lat, static_cast<index_t>(bars.size()), [&](index_t q) { return lat.bar_centre(bars[q]); },
      [&](index_t q) { return bars[q]; }, 0);
}

std::vector<double> evaluate_field_modules(const Field& f, const Lattice& lat) {
  const auto nm = static_cast<index_t>(lat.num_modules());
  return evaluate_at(
      f, lat, nm, [&](index_t m) { return lat.position(lat.num_corners() + m); }, same,
      kModuleStream);
}

std::vector<double> evaluate_field_modules(const Field& f, const Lattice& lat,
                                           const std::vector<index_t>& modules) {
  return evaluate_at(
      f, lat, static_cast<index_t>(modules.size()),
      [&](index_t q) { return lat.position(lat.num_corners() + modules[q]); },
      [&](index_t q) { return modules[q]; }, kModuleStream);
}

std::vector<double> correlated_gaussian(const Lattice& lat, const std::vector<Vec3>& points,
                                        double ell, Field::Covariance covariance,
                                        std::uint64_t seed) {
  const double h = ell / 8.0;
  const double ext[3] = {lat.nx() * lat.L(), lat.ny() * lat.L(), lat.nz() * lat.L()};
  int n[3];
  for (int a = 0; a < 3; ++a) {
    n[a] = static_cast<int>(std::ceil((ext[a] + 3.0 * ell) / h)) + 1;
    n[a] += n[a] % 2; // even sizes
  }
  const std::size_t total = std::size_t(n[0]) * n[1] * n[2];
  const int nzc = n[2] / 2 + 1; // complex points along the last axis (r2c)
  const std::size_t ctotal = std::size_t(n[0]) * n[1] * nzc;
  double* real = fftw_alloc_real(total);
  fftw_complex* spec = fftw_alloc_complex(ctotal);
  fftw_complex* noise = fftw_alloc_complex(ctotal);
  // Covariance on the periodic grid (minimum-image distance); index (i, j, k), k fastest.
  for (int i = 0; i < n[0]; ++i)
    for (int j = 0; j < n[1]; ++j)
      for (int k = 0; k < n[2]; ++k) {
        const double dx = std::min(i, n[0] - i) * h, dy = std::min(j, n[1] - j) * h,
                     dz = std::min(k, n[2] - k) * h;
        const double r = std::sqrt(dx * dx + dy * dy + dz * dz) / ell;
        real[(std::size_t(i) * n[1] + j) * n[2] + k] =
            covariance == Field::Covariance::Exponential ? std::exp(-r) : std::exp(-r * r);
      }
  fftw_plan fwd_c = fftw_plan_dft_r2c_3d(n[0], n[1], n[2], real, spec, FFTW_ESTIMATE);
  fftw_execute(fwd_c);
  fftw_destroy_plan(fwd_c);
  // White noise N(0, 1) per grid point (Box-Muller on the counter-based uniforms).
  for (std::size_t p = 0; p < total; ++p) {
    const double u1 = counter_uniform(seed, 2 * p), u2 = counter_uniform(seed, 2 * p + 1);
    real[p] = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  fftw_plan fwd_w = fftw_plan_dft_r2c_3d(n[0], n[1], n[2], real, noise, FFTW_ESTIMATE);
  fftw_execute(fwd_w);
  fftw_destroy_plan(fwd_w);
  // X = F^-1 sqrt(eigenvalues of the circulant covariance) F W; FFTW's inverse is unnormalised.
  for (std::size_t p = 0; p < ctotal; ++p) {
    const double lam = std::max(spec[p][0], 0.0);
    const double s = std::sqrt(lam) / static_cast<double>(total);
    noise[p][0] *= s;
    noise[p][1] *= s;
  }
  fftw_plan inv = fftw_plan_dft_c2r_3d(n[0], n[1], n[2], noise, real, FFTW_ESTIMATE);
  fftw_execute(inv);
  fftw_destroy_plan(inv);
  std::vector<double> v(points.size());
  for (std::size_t b = 0; b < points.size(); ++b) {
    const Vec3 c = points[b];
    const auto at = [&](double x, int a) {
      return std::clamp(static_cast<int>(std::lround(x / h)), 0, n[a] - 1);
    };
    v[b] = real[(std::size_t(at(c.x, 0)) * n[1] + at(c.y, 1)) * n[2] + at(c.z, 2)];
  }
  fftw_free(real);
  fftw_free(spec);
  fftw_free(noise);
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
    return fmt::format("Weibull: mean {:g}, cv {:g} (shape {:.4g}, scale {:.6g}), seed {}{}",
                       f.mean, f.cv, g, weibull_scale(f.mean, g), f.seed,
                       f.correlation_length > 0
                           ? fmt::format(", correlated over {:g} m ({})", f.correlation_length,
                                         f.covariance == Field::Covariance::Exponential
                                             ? "exponential"
                                             : "squared exponential")
                           : std::string(", independent per bar"));
  }
  }
  return "";
}

} // namespace ldem
