// Scalar functions of time that scale loads and imposed velocities: sums of terms.
#pragma once

#include <limits>
#include <string>
#include <variant>
#include <vector>

namespace ldem {

// Every term has a window [t_start, t_end): outside it the term is 0, inside it the term's own
// time is s = t - t_start (a ramp starts at t_start, a table's times count from it).
inline constexpr double kNever = std::numeric_limits<double>::infinity();

// value
struct Constant {
  double value = 1.0;
  double t_start = 0.0, t_end = kNever;
};
// value * min(s / duration, 1)
struct LinearRamp {
  double value = 1.0, duration = 0.0;
  double t_start = 0.0, t_end = kNever;
};
// value * (1 - exp(-s / tau))
struct ExponentialRise {
  double value = 1.0, tau = 0.0;
  double t_start = 0.0, t_end = kNever;
};
// amplitude(s) * sin(2 pi f s), where the amplitude grows exponentially with time constant tau
// up to `amplitude`, reached after n_cycles cycles and kept constant afterwards: amplitude(s) =
// amplitude * exp((min(s, n_cycles / f) - n_cycles / f) / tau).
struct GrowingSine {
  double amplitude = 0.0, frequency = 0.0, t_start = 0.0, tau = 0.0, n_cycles = 0.0;
  double t_end = kNever;
};
// Points (times[i], values[i]), times increasing: linear between them, values[0] before the
// first and the last value after the last.
struct Tabulated {
  std::vector<double> times, values;
  double t_start = 0.0, t_end = kNever;
};

using TimeTerm = std::variant<Constant, LinearRamp, ExponentialRise, GrowingSine, Tabulated>;

class TimeFunction {
public:
  TimeFunction() : terms_{Constant{1.0}} {}
  explicit TimeFunction(std::vector<TimeTerm> terms); // throws InputError on bad parameters
  double operator()(double t) const noexcept;
  const std::vector<TimeTerm>& terms() const { return terms_; }

private:
  std::vector<TimeTerm> terms_;
};

} // namespace ldem
