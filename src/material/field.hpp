// Property fields: a bar property given as a constant, a linear grading along an axis, a
// table of (coordinate, value) pairs along an axis, or a random Weibull field. A field is
// evaluated per bar (at the bar's centre, or from the bar's global number for random draws),
// so the result does not depend on threads or on how the lattice is split.
#pragma once

#include "lattice/lattice.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace ldem {

struct Field {
  enum class Kind { Constant, Linear, Table, Weibull } kind = Kind::Constant;
  double value = 0.0;                           // Constant
  int axis = 2;                                 // Linear, Table: 0, 1, 2
  std::vector<std::pair<double, double>> table; // Linear (2 points), Table: (coordinate, value)
  double mean = 0.0, cv = 0.0;                  // Weibull
  std::uint64_t seed = 1;                       // Weibull
  // Weibull with correlation_length > 0: a spatially correlated field (see below).
  double correlation_length = 0.0;
  enum class Covariance { Exponential, SquaredExponential } covariance = Covariance::Exponential;

  static Field constant(double v) {
    Field f;
    f.value = v;
    return f;
  }
  bool varies() const { return kind != Kind::Constant; }
};

// Checks a field against the body (a grading must lie inside it, a table must be sorted, a
// Weibull CV must admit a shape) and throws InputError naming `what` otherwise.
void validate_field(const Field& f, const Lattice& lattice, const std::string& what);

// The field's value for every bar of the lattice (at its centre).
std::vector<double> evaluate_field(const Field& f, const Lattice& lattice);
// The field's value for every module (at its centre): densities, for the lumped masses.
std::vector<double> evaluate_field_modules(const Field& f, const Lattice& lattice);
// The same values for some bars or modules only (their numbers in `lattice`, in that order):
// a distributed run's window, which need not evaluate the whole body.
std::vector<double> evaluate_field(const Field& f, const Lattice& lattice,
                                   const std::vector<index_t>& bars);
std::vector<double> evaluate_field_modules(const Field& f, const Lattice& lattice,
                                           const std::vector<index_t>& modules);

// Weibull shape g from the coefficient of variation: CV^2 = G(1 + 2/g) / G(1 + 1/g)^2 - 1.
// Throws InputError when no shape gives that CV (CV <= 0 or above the g -> 0 limit used).
double weibull_shape(double cv);
// Scale from the mean: mean = scale G(1 + 1/g).
double weibull_scale(double mean, double shape);
// A uniform number in (0, 1) from (seed, index) alone: a counter-based generator, so that
// bar b's draw is the same whatever the order or the thread that computes it.
double counter_uniform(std::uint64_t seed, std::uint64_t index);

// A stationary Gaussian field of zero mean and unit variance with covariance
// exp(-r / l) (exponential) or exp(-(r / l)^2) (squared exponential), l the correlation length,
// made by circulant embedding on a periodic grid of spacing l / 8 that covers the body plus
// 3 l of padding per axis (FFT, FFTW), and taken at each bar's centre (nearest grid point, so
// the marginal stays exactly standard normal). The grid depends on the body and l, not on L:
// a coarse and a fine lattice of the same body get the same physical field. A correlated
// Weibull field maps it through the normal CDF to the Weibull marginal.
// `points`: where to take it (bar or module centres).
std::vector<double> correlated_gaussian(const Lattice& lattice, const std::vector<Vec3>& points,
                                        double correlation_length, Field::Covariance covariance,
                                        std::uint64_t seed);

std::string describe_field(const Field& f);

} // namespace ldem
