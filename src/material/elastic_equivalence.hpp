// Riera's elastic equivalence between the cubic truss and an isotropic solid
// (paper eq. 1) and the fracture areas that make a split module dissipate Gf L^2
// (paper eqs. 3-6).
#pragma once

#include <cmath>

namespace ldem {

struct ElasticEquivalence {
  double delta;       // 9 nu / (4 - 8 nu)
  double phi;         // (9 + 8 delta) / (18 + 24 delta)
  double area_normal; // A_l / L^2 = phi
  double area_diag;   // A_d / L^2 = (2 / sqrt 3) delta phi
};

inline ElasticEquivalence elastic_equivalence(double nu) {
  const double delta = 9.0 * nu / (4.0 - 8.0 * nu);
  const double phi = (9.0 + 8.0 * delta) / (18.0 + 24.0 * delta);
  return {delta, phi, phi, 2.0 / std::sqrt(3.0) * delta * phi};
}

// Fracture areas over L^2 (eq. 6): a plane parallel to a face cuts, per module,
// one edge-bar equivalent (4 edges x 1/4), one centre-centre bar and 4 diagonals:
// 2 x 3/22 + 4 x 4/22 = 1.
inline constexpr double kFractureAreaNormal = 3.0 / 22.0;
inline constexpr double kFractureAreaDiag = 4.0 / 22.0;

// The single ratio A^f / A the paper's eq. 16 and the original code use for both kinds.
inline constexpr double kPaperSingleRatio = 0.34;

} // namespace ldem
