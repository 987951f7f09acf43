#include "solver/time_function.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>

namespace ldem {

namespace {
void positive(double v, const char* what) {
  if (!(v > 0.0) || !std::isfinite(v))
    throw InputError(fmt::format("time function: {} must be positive, got {:g}", what, v));
}
} // namespace

TimeFunction::TimeFunction(std::vector<TimeTerm> terms) : terms_(std::move(terms)) {
  for (const TimeTerm& term : terms_) {
    if (const auto* r = std::get_if<LinearRamp>(&term))
      positive(r->duration, "ramp duration");
    else if (const auto* e = std::get_if<ExponentialRise>(&term))
      positive(e->tau, "exponential rise time constant tau");
    else if (const auto* s = std::get_if<GrowingSine>(&term)) {
      positive(s->frequency, "sine frequency");
      positive(s->tau, "sine growth time constant tau");
      if (!(s->n_cycles >= 0.0))
        throw InputError(
            fmt::format("time function: n_cycles must be >= 0, got {:g}", s->n_cycles));
    }
  }
}

double TimeFunction::operator()(double t) const noexcept {
  double sum = 0.0;
  for (const TimeTerm& term : terms_) {
    sum += std::visit(
        [t](const auto& f) -> double {
          using T = std::decay_t<decltype(f)>;
          if constexpr (std::is_same_v<T, Constant>)
            return f.value;
          else if constexpr (std::is_same_v<T, LinearRamp>)
            return f.value * std::min(t / f.duration, 1.0);
          else if constexpr (std::is_same_v<T, ExponentialRise>)
            return f.value * (1.0 - std::exp(-t / f.tau));
          else {
            const double s = t - f.t_start;
            if (s < 0.0)
              return 0.0;
            const double t_full = f.n_cycles / f.frequency;
            const double amp = f.amplitude * std::exp((std::min(s, t_full) - t_full) / f.tau);
            return amp * std::sin(2.0 * std::numbers::pi * f.frequency * s);
          }
        },
        term);
  }
  return sum;
}

} // namespace ldem
