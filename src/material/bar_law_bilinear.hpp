// The bilinear (Hillerborg-type) bar law of paper eqs. 7-17, as a pure value type.
//
// Strain e = (l - l0) / l0. The history h is the largest strain the bar has reached,
// never below e_p (so an intact bar has h = e_p). Force:
//   e <= 0                : F = EA e                  (compression, undamaged stiffness)
//   0 < e, max(h, e) = m  : F = EA e g(m),  g(m) = e_p (e_r - m) / ((e_r - e_p) m) in [0, 1]
// i.e. linear up to e_p, linear softening to zero at e_r on the envelope, and unloading
// and reloading along the secant to the origin. A pre-cracked bar has h = +infinity: it
// carries compression only and has dissipated nothing in this run.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace ldem {

enum class BarState : unsigned char { Intact, Softening, Broken };

struct BilinearLaw {
  double EA;  // axial stiffness times area [N]
  double l0;  // reference length [m]
  double e_p; // strain at peak force
  double e_r; // strain at rupture, e_r = K_r e_p > e_p

  static constexpr double kPrecracked = std::numeric_limits<double>::infinity();

  double initial_history() const noexcept { return e_p; }
  static double next_history(double h, double e) noexcept { return std::max(h, e); }

  // Secant factor g(m) written as num / den, so that the hot loop needs one division.
  struct Secant {
    double num, den;
  };
  Secant secant(double e, double h) const noexcept {
    if (!(e > 0.0))
      return {1.0, 1.0};
    const double m = std::max(h, e);
    return {std::max(e_p * (e_r - m), 0.0), (e_r - e_p) * m};
  }

  double force(double e, double h) const noexcept {
    const Secant g = secant(e, h);
    return EA * e * g.num / g.den;
  }

  // Envelope force at a largest strain m >= e_p.
  double envelope(double m) const noexcept {
    return m >= e_r ? 0.0 : EA * e_p * (e_r - m) / (e_r - e_p);
  }

  // Recoverable energy at strain e with history h: the area under the secant (or the
  // elastic line in compression) times l0.
  double stored_energy(double e, double h) const noexcept { return 0.5 * force(e, h) * e * l0; }

  // Energy dissipated so far: the triangle O-A-P of the paper's Fig. 1c, A = (e_p, EA e_p)
  // the peak and P = (m, F_env(m)) the current point of the envelope, times l0:
  //   D = l0 (m EA e_p - e_p F_env(m)) / 2,
  // which for m >= e_r is EA e_p e_r l0 / 2 = Gf A^f by the choice of K_r (eq. 11).
  double dissipated_energy(double h) const noexcept {
    if (std::isinf(h) || h <= e_p)
      return 0.0; // pre-cracked, or never past the peak (exactly 0, not a round-off residue)
    const double m = std::min(h, e_r);
    return 0.5 * l0 * (m * EA * e_p - e_p * envelope(m));
  }

  BarState state(double h) const noexcept {
    if (h >= e_r)
      return BarState::Broken;
    return h > e_p ? BarState::Softening : BarState::Intact;
  }
};

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
