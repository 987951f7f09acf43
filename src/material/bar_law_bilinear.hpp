// The bilinear (Hillerborg-type) bar law of paper eqs. 7-17, `law = "bilinear"`.
//
// Strain e = (l - l0) / l0. The state is the history h, the largest strain the bar has
// reached until it broke (the first strain at or past e_r), never below e_p (so an intact bar
// has h = e_p). Force:
//   e <= 0                : F = EA e                  (compression, undamaged stiffness)
//   0 < e, max(h, e) = m  : F = EA e g(m),  g(m) = e_p (e_r - m) / ((e_r - e_p) m) in [0, 1]
// i.e. linear up to e_p, linear softening to zero at e_r on the envelope, and unloading
// and reloading along the secant to the origin. A pre-cracked bar has h = +infinity: it
// carries compression only and has dissipated nothing in this run.
#pragma once

#include "lattice/lattice.hpp"
#include "material/bar_law.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace ldem {

class BarTable;

struct BilinearLaw {
  double e_p; // strain at peak force
  double e_r; // strain at rupture, e_r = K_r e_p > e_p

  static constexpr std::string_view kName = "bilinear";
  // The history is not written to the snapshots: their state and damage show it.
  static constexpr std::array<StateArray, 1> kStateArrays{{{"history", false}}};
  struct State {
    double h;
  };
  static State read(const double* const* arrays, std::int64_t i) noexcept { return {arrays[0][i]}; }
  static void write(double* const* arrays, std::int64_t i, State s) noexcept { arrays[0][i] = s.h; }

  static constexpr double kPrecracked = std::numeric_limits<double>::infinity();
  State initial() const noexcept { return {e_p}; }
  static State precracked() noexcept { return {kPrecracked}; }
  bool pristine(State s) const noexcept { return s.h == e_p; }
  double elastic_limit() const noexcept { return e_p; }

  // s = F / l = k (l - l0) g / l, with g = num / den so that the vector loop needs one
  // division, and g = 1 in compression.
  double force_over_length(double k, Stretch g, State s) const noexcept {
    const double m = g.e > s.h ? g.e : s.h;
    const bool tension = g.e > 0.0;
    const double num_t = e_p * (e_r - m);
    const double num = tension ? (num_t > 0.0 ? num_t : 0.0) : 1.0;
    const double den = tension ? (e_r - e_p) * m : 1.0;
    return k * g.dl * num / (g.l * den);
  }
  // The axial force F = s l.
  double force(double k, Stretch g, State s) const noexcept {
    return force_over_length(k, g, s) * g.l;
  }

  // A broken bar's history stays where it broke: from e_r on the force (nothing in tension,
  // EA e in compression), the dissipation and the state no longer depend on it, so the slow
  // path has nothing to do for the bars of an opening crack. (`&`, not `&&`: with the branch
  // GCC 12 left the general kernel's loop scalar, and the FGM plate's second half took 1.3
  // times as long.)
  bool changes(double e, State s) const noexcept { return (e > s.h) & (s.h < e_r); }
  // The history rises to e; the bar softens when it first passes e_p and breaks at e_r.
  template <class Emit> void update(double e, State& s, Emit&& emit) const {
    if (s.h <= e_p && e > e_p)
      emit(BarState::Softening);
    if (s.h < e_r && e >= e_r)
      emit(BarState::Broken);
    s.h = e;
  }

  // The area under the secant (or the elastic line in compression): F (l - l0) / 2.
  static double elastic_energy(double s_over_l, Stretch g, State) noexcept {
    return 0.5 * s_over_l * g.l * g.dl;
  }

  // Envelope force at a largest strain m >= e_p.
  double envelope(double EA, double m) const noexcept {
    return m >= e_r ? 0.0 : EA * e_p * (e_r - m) / (e_r - e_p);
  }

  // Energy dissipated so far: the triangle O-A-P of the paper's Fig. 1c, A = (e_p, EA e_p)
  // the peak and P = (m, F_env(m)) the current point of the envelope, times l0:
  //   D = l0 (m EA e_p - e_p F_env(m)) / 2,
  // which for m >= e_r is EA e_p e_r l0 / 2 = Gf A^f by the choice of K_r (eq. 11).
  double dissipated_energy(double EA, double l0, State s) const noexcept {
    if (std::isinf(s.h) || s.h <= e_p)
      return 0.0; // pre-cracked, or never past the peak (exactly 0, not a round-off residue)
    const double m = std::min(s.h, e_r);
    return 0.5 * l0 * (m * EA * e_p - e_p * envelope(EA, m));
  }
  // What a broken bar has dissipated, EA e_p e_r l0 / 2: damage is D over it (a pre-cracked
  // bar counts as fully damaged).
  double damage(double EA, double l0, State s) const noexcept {
    return std::isinf(s.h) ? 1.0 : dissipated_energy(EA, l0, s) / (0.5 * EA * e_p * e_r * l0);
  }

  BarState state(State s) const noexcept {
    if (s.h >= e_r)
      return BarState::Broken;
    return s.h > e_p ? BarState::Softening : BarState::Intact;
  }

  // The constants of a row of bars as the kernels read them: the family's, or per bar (a
  // material that varies: the table's per-bar arrays from the row's first bar on).
  struct Row;
  static Row row(const BarTable& table, int family, index_t first_bar);
  template <bool PerBar> static BilinearLaw at(const Row& row, std::int64_t i) noexcept;
};

struct BilinearLaw::Row {
  BilinearLaw family;
  const double* e_p;
  const double* e_r;
};

template <bool PerBar> BilinearLaw BilinearLaw::at(const Row& row, std::int64_t i) noexcept {
  if constexpr (PerBar)
    return {row.e_p[i], row.e_r[i]};
  else
    return row.family;
}

static_assert(BarLaw<BilinearLaw>);

// e_p from the failure factor R_f (eq. 7).
inline double failure_strain(double R_f, double Gf, double E, double nu) {
  return R_f * std::sqrt(Gf / (E * (1.0 - nu * nu)));
}

// K_r of eq. 12 for a bar of reference length l0 and fracture-area ratio A^f / A.
inline double ductility(double Gf, double E, double e_p, double area_ratio, double l0) {
  return Gf / (E * e_p * e_p) * area_ratio * 2.0 / l0;
}

// Critical length L_cr of eq. 13: K_r = L_cr / l0.
inline double critical_length(double Gf, double E, double e_p, double area_ratio) {
  return 2.0 * Gf / (E * e_p * e_p) * area_ratio;
}

} // namespace ldem
