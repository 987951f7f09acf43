// The bilinear law with a fatigue life, `law = "bilinear_fatigue"` (docs/model.md, "Fatigue").
//
// Force, softening and dissipation are the bilinear law's (bar_law_bilinear.hpp). Each bar
// also has a remaining life lambda, 1 at the start, which cycles of its tensile strain
// e+ = max(e, 0) use up:
// - cycles are counted from the turning points of e+: a peak (or valley) is confirmed once e+
//   has come back from it by more than the gate g, so that ringing smaller than g does not
//   count; each half-cycle between confirmed turning points has a range D;
// - a half-cycle with D above the threshold D_th uses up A_l D^m / 2 of lambda, so that a
//   constant-amplitude cycle of range D breaks the bar after N = 1 / (A_l D^m) cycles (the
//   rainflow count of such a history is the same);
// - A_l = A (l0 / l_ref)^(m / 2 - 1) for a bar of length l0, A being given for bars of length
//   l_ref: the scaling that keeps Paris' C independent of the module size (docs/model.md);
// - a bar whose life is used up breaks: it takes the bilinear law's broken state (nothing in
//   tension, the undamaged stiffness in compression); the elastic energy it held at that moment
//   is booked as `fatigue_dissipated`, so that the energy balance still closes, and what its
//   softening had dissipated is kept apart (dissipated_before).
// The counting runs at the start of every count_every-th step on the current displacements
// (cycle_count.hpp), apart from the step's kernels, which see the bilinear law.
#pragma once

#include "material/bar_law_bilinear.hpp"

#include <array>
#include <cmath>
#include <limits>

namespace ldem {

// The fatigue constants of the bars of one family.
struct FatigueConstants {
  double A = 0.0;         // life used per cycle at a strain range of 1, for this family's length
  double m = 1.0;         // exponent
  double threshold = 0.0; // strain ranges at or below it use no life
  double gate = 0.0;      // hysteresis of the turning points (> 0)
};

// The law value is the bilinear law's constants alone, so that the step's kernels see what
// they see for the bilinear law; the fatigue constants are the count's (fatigue_constants).
struct BilinearFatigueLaw {
  BilinearLaw bilinear;

  static constexpr std::string_view kName = "bilinear_fatigue";
  // history: the bilinear law's, set to +infinity (a broken bar's, as a pre-cracked one) once
  // the bar's life has run out; life: lambda; fatigue_released: the elastic energy the bar held
  // when its life ran out; dissipated_before: what its softening had dissipated by then (the
  // bilinear law counts nothing for an infinite history); cycle_turn and cycle_extreme: the
  // last confirmed turning point of e+ and the extreme reached since (rising while
  // extreme >= turn); life_at_window: the life at the start of cycle jumping's resolved
  // window. The step's kernels read the history alone and are the bilinear law's own; the
  // count reads and writes the others.
  static constexpr std::array<StateArray, 7> kStateArrays{{{"history", false},
                                                           {"life", true},
                                                           {"fatigue_released", false},
                                                           {"dissipated_before", false},
                                                           {"cycle_turn", false},
                                                           {"cycle_extreme", false},
                                                           {"life_at_window", false}}};
  static constexpr std::size_t kLife = 1, kReleased = 2, kDissipatedBefore = 3, kTurn = 4,
                               kExtreme = 5;
  using State = BilinearLaw::State;
  static State read(const double* const* arrays, std::int64_t i) noexcept { return {arrays[0][i]}; }
  static void write(double* const* arrays, std::int64_t i, State s) noexcept { arrays[0][i] = s.h; }
  // The life of a new bar (the count's arrays start at 0).
  static constexpr double kNewLife = 1.0;

  State initial() const noexcept { return bilinear.initial(); }
  // A pre-cracked bar is the bilinear law's; it has no life to count (its life is set to 0).
  static State precracked() noexcept { return BilinearLaw::precracked(); }
  bool pristine(State s) const noexcept { return bilinear.pristine(s); }
  double elastic_limit() const noexcept { return bilinear.elastic_limit(); }
  double force_over_length(double k, Stretch g, State s) const noexcept {
    return bilinear.force_over_length(k, g, s);
  }
  bool changes(double e, State s) const noexcept { return bilinear.changes(e, s); }
  template <class Emit> void update(double e, State& s, Emit&& emit) const {
    bilinear.update(e, s, emit);
  }
  static double elastic_energy(double s_over_l, Stretch g, State s) noexcept {
    return BilinearLaw::elastic_energy(s_over_l, g, s);
  }
  // The softening's dissipation (0 once the life ran out: dissipated_before keeps it then).
  double dissipated_energy(double EA, double l0, State s) const noexcept {
    return bilinear.dissipated_energy(EA, l0, s);
  }
  double damage(double EA, double l0, State s) const noexcept {
    return bilinear.damage(EA, l0, s);
  }
  BarState state(State s) const noexcept { return bilinear.state(s); }
  // Whether the count concerns a bar: not broken (by its life, by the bilinear law or before
  // the run).
  bool counting(State s) const noexcept { return s.h < bilinear.e_r; }
  // A bar's life running out at stretch g, its stiffness k and E A: what it releases (its
  // elastic energy, in tension; in compression it keeps carrying the same force), what its
  // softening had dissipated, and its new state, broken.
  struct Release {
    double released, dissipated;
  };
  Release release(double k, double EA, double l0, Stretch g, State& s) const noexcept {
    const Release r{g.e > 0.0 ? elastic_energy(force_over_length(k, g, s), g, s) : 0.0,
                    dissipated_energy(EA, l0, s)};
    s.h = BilinearLaw::kPrecracked;
    return r;
  }

  // One sample of the tensile strain x = max(e, 0) into the cycle count (turn, extreme); the
  // life a confirmed half-cycle uses up is returned (0 when none was confirmed).
  static double count(const FatigueConstants& fatigue, double x, double& turn,
                      double& extreme) noexcept {
    double used = 0.0;
    if (extreme >= turn) { // rising
      if (x > extreme) {
        extreme = x;
      } else if (extreme - x > fatigue.gate) {
        used = half_cycle(fatigue, extreme - turn);
        turn = extreme;
        extreme = x;
      }
    } else { // falling
      if (x < extreme) {
        extreme = x;
      } else if (x - extreme > fatigue.gate) {
        used = half_cycle(fatigue, turn - extreme);
        turn = extreme;
        extreme = x;
      }
    }
    return used;
  }
  static double half_cycle(const FatigueConstants& fatigue, double range) noexcept {
    return range > fatigue.threshold ? 0.5 * fatigue.A * std::pow(range, fatigue.m) : 0.0;
  }

  struct Row;
  static Row row(const BarTable& table, int family, index_t first_bar);
  template <bool PerBar> static BilinearFatigueLaw at(const Row& row, std::int64_t i) noexcept;
  // The fatigue constants of a family's bars (A scaled to their length, the gate resolved).
  static FatigueConstants fatigue_constants(const BarTable& table, int family);
};

struct BilinearFatigueLaw::Row {
  BilinearFatigueLaw family;
  const double* e_p;
  const double* e_r;
};

template <bool PerBar>
BilinearFatigueLaw BilinearFatigueLaw::at(const Row& row, std::int64_t i) noexcept {
  if constexpr (PerBar)
    return {{row.e_p[i], row.e_r[i]}};
  else
    return row.family;
}

static_assert(BarLaw<BilinearFatigueLaw>);

// The gate when a case gives none: this fraction of the family's e_p.
inline constexpr double kDefaultGate = 0.01;

// A_l of a bar of length l0: A (l0 / l_ref)^(m / 2 - 1).
inline double fatigue_coefficient(double A, double m, double l0, double l_ref) {
  return A * std::pow(l0 / l_ref, 0.5 * m - 1.0);
}

} // namespace ldem
