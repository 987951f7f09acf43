#include "solver/time_function.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <utility>

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
    } else if (const auto* p = std::get_if<Tabulated>(&term)) {
      if (p->times.empty() || p->times.size() != p->values.size())
        throw InputError("time function: a table needs at least one point [t, value]");
      for (std::size_t i = 0; i < p->times.size(); ++i) {
        if (!std::isfinite(p->times[i]) || !std::isfinite(p->values[i]))
          throw InputError(fmt::format("time function: table point {} is not finite", i));
        if (i > 0 && !(p->times[i] > p->times[i - 1]))
          throw InputError(fmt::format(
              "time function: table times must increase, got {:g} after {:g} (point {})",
              p->times[i], p->times[i - 1], i));
      }
    }
    const auto [t_start, t_end] =
        std::visit([](const auto& f) { return std::pair{f.t_start, f.t_end}; }, term);
    if (!(t_start >= 0.0) || !std::isfinite(t_start))
      throw InputError(fmt::format("time function: t_start must be >= 0, got {:g}", t_start));
    if (!(t_end > t_start))
      throw InputError(fmt::format(
          "time function: t_end must be after t_start, got t_end = {:g}, t_start = {:g}", t_end,
          t_start));
  }
}

double TimeFunction::operator()(double t) const noexcept {
  double sum = 0.0;
  for (const TimeTerm& term : terms_) {
    sum += std::visit(
        [t](const auto& f) -> double {
          using T = std::decay_t<decltype(f)>;
          const double s = t - f.t_start;
          if (s < 0.0 || t >= f.t_end)
            return 0.0;
          if constexpr (std::is_same_v<T, Constant>) {
            return f.value;
          } else if constexpr (std::is_same_v<T, LinearRamp>) {
            return f.value * std::min(s / f.duration, 1.0);
          } else if constexpr (std::is_same_v<T, ExponentialRise>) {
            return f.value * (1.0 - std::exp(-s / f.tau));
          } else if constexpr (std::is_same_v<T, GrowingSine>) {
            const double t_full = f.n_cycles / f.frequency;
            const double amp = f.amplitude * std::exp((std::min(s, t_full) - t_full) / f.tau);
            return amp * std::sin(2.0 * std::numbers::pi * f.frequency * s);
          } else {
            // The segment [times[i - 1], times[i]) that holds s, by bisection.
            const auto& x = f.times;
            const auto& y = f.values;
            if (s <= x.front())
              return y.front();
            if (s >= x.back())
              return y.back();
            const std::size_t i = static_cast<std::size_t>(
                std::upper_bound(x.begin(), x.end(), s) - x.begin());
            const double w = (s - x[i - 1]) / (x[i] - x[i - 1]);
            return y[i - 1] + w * (y[i] - y[i - 1]);
          }
        },
        term);
  }
  return sum;
}

} // namespace ldem
