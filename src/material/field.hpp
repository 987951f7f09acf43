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

  static Field constant(double v) { return {Kind::Constant, v, 2, {}, 0, 0, 1}; }
  bool varies() const { return kind != Kind::Constant; }
};

// Checks a field against the body (a grading must lie inside it, a table must be sorted, a
// Weibull CV must admit a shape) and throws InputError naming `what` otherwise.
void validate_field(const Field& f, const Lattice& lattice, const std::string& what);

// The field's value for every bar of the lattice.
std::vector<double> evaluate_field(const Field& f, const Lattice& lattice);

// Weibull shape g from the coefficient of variation: CV^2 = G(1 + 2/g) / G(1 + 1/g)^2 - 1.
// Throws InputError when no shape gives that CV (CV <= 0 or above the g -> 0 limit used).
double weibull_shape(double cv);
// Scale from the mean: mean = scale G(1 + 1/g).
double weibull_scale(double mean, double shape);
// A uniform number in (0, 1) from (seed, index) alone: a counter-based generator, so that
// bar b's draw is the same whatever the order or the thread that computes it.
double counter_uniform(std::uint64_t seed, std::uint64_t index);

std::string describe_field(const Field& f);

} // namespace ldem
