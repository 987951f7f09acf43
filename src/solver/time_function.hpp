// Scalar functions of time that scale loads and imposed velocities: sums of terms.
#pragma once

#include <string>
#include <variant>
#include <vector>

namespace ldem {

// value
struct Constant {
  double value = 1.0;
};
// value * min(t / duration, 1)
struct LinearRamp {
  double value = 1.0, duration = 0.0;
};
// value * (1 - exp(-t / tau))
struct ExponentialRise {
  double value = 1.0, tau = 0.0;
};
// Starting at t_start, amplitude(s) * sin(2 pi f s) with s = t - t_start, where the amplitude
// grows exponentially with time constant tau up to `amplitude`, reached after n_cycles cycles
// and kept constant afterwards: amplitude(s) = amplitude * exp((min(s, n_cycles / f) -
// n_cycles / f) / tau). Zero before t_start.
struct GrowingSine {
  double amplitude = 0.0, frequency = 0.0, t_start = 0.0, tau = 0.0, n_cycles = 0.0;
};

using TimeTerm = std::variant<Constant, LinearRamp, ExponentialRise, GrowingSine>;

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
