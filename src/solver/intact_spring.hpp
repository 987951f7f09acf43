// The arithmetic of a pristine bar (a linear spring, bar_law.hpp) on AVX-512, shared by the
// bar pass's intact kernel and the node kernel's fast links so that both give the same bits
// (internal to the solver).
#pragma once

#include "lattice/lattice.hpp"

#if defined(__AVX512F__)
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <immintrin.h>

namespace ldem {

#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip these warnings on _mm512_rsqrt14_pd and _mm512_rcp14_pd (a known
// false alarm: their unused pass-through operand).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

// 1 / sqrt(x) to about an ulp without the divider: the 14-bit estimate y0, then one step of
// third order, y = y0 (1 + e/2 + 3e^2/8 + 5e^3/16) with e = 1 - x y0^2: the series of
// (1 - e)^(-1/2) cut after its e^3 term, |e| < 2^-14 leaving 35 e^4 / 128 < 2^-57 (two Newton
// steps would take one operation more).
inline __m512d inv_sqrt(__m512d x) {
  const __m512d y = _mm512_rsqrt14_pd(x);
  const __m512d e = _mm512_fnmadd_pd(_mm512_mul_pd(x, y), y, _mm512_set1_pd(1.0));
  const __m512d p =
      _mm512_fmadd_pd(_mm512_fmadd_pd(_mm512_set1_pd(5.0 / 16.0), e, _mm512_set1_pd(3.0 / 8.0)), e,
                      _mm512_set1_pd(0.5));
  return _mm512_fmadd_pd(_mm512_mul_pd(y, e), p, y);
}

// acc + w (l - l0)^2 for the lanes m of a vector of intact bars, with u the relative
// displacement (d = d0 + u), l^2 and y = 1 / l as computed for their force, w = end_scale on
// the lanes `ends` (a bar row's first and last bars) and 1 elsewhere. l - l0 is
// (l^2 - l0^2) / (l + l0) with l^2 - l0^2 = u . (u + 2 d0): no cancellation, and exactly 0 for
// an unstrained bar; the reciprocal from the 14-bit estimate and two Newton steps.
// (The weights as a vector w: a shaped body's bars weigh their area factors.)
inline __m512d add_intact_energy(__m512d acc, __m512d ux, __m512d uy, __m512d uz, Vec3 d0,
                                 __m512d l2, __m512d y, double l0, __mmask8 m, __m512d w) {
  const __m512d vx = _mm512_set1_pd(d0.x), vy = _mm512_set1_pd(d0.y), vz = _mm512_set1_pd(d0.z);
  const __m512d v2 = _mm512_set1_pd(2.0);
  const __m512d q =
      _mm512_fmadd_pd(ux, _mm512_add_pd(ux, _mm512_add_pd(vx, vx)),
                      _mm512_fmadd_pd(uy, _mm512_add_pd(uy, _mm512_add_pd(vy, vy)),
                                      _mm512_mul_pd(uz, _mm512_add_pd(uz, _mm512_add_pd(vz, vz)))));
  const __m512d den = _mm512_fmadd_pd(l2, y, _mm512_set1_pd(l0));
  __m512d rc = _mm512_rcp14_pd(den);
  rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
  rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
  const __m512d dl = _mm512_maskz_mul_pd(m, q, rc);
  return _mm512_fmadd_pd(_mm512_mul_pd(w, dl), dl, acc);
}

inline __m512d end_weights(__mmask8 ends, double end_scale) {
  return _mm512_mask_blend_pd(ends, _mm512_set1_pd(1.0), _mm512_set1_pd(end_scale));
}

inline __m512d add_intact_energy(__m512d acc, __m512d ux, __m512d uy, __m512d uz, Vec3 d0,
                                 __m512d l2, __m512d y, double l0, __mmask8 m, __mmask8 ends,
                                 double end_scale) {
  return add_intact_energy(acc, ux, uy, uz, d0, l2, y, l0, m, end_weights(ends, end_scale));
}

// The lanes of a vector of 8 from index i on whose indices lie in [lo, hi).
inline __mmask8 lanes_in(std::int64_t i, std::int64_t lo, std::int64_t hi) {
  const std::int64_t a = std::clamp<std::int64_t>(lo - i, 0, 8),
                     b = std::clamp<std::int64_t>(hi - i, 0, 8);
  return static_cast<__mmask8>(((1u << b) - 1u) & ~((1u << a) - 1u));
}

// A shaped body's area factors of a vector of 8 bars (StepLayout::bar_code): x times 1/4, 1/2
// and 3/4 on the lanes q1, q2 and q3 (exact factors: the product is x f rounded once).
inline __m512d times_quarters(__m512d x, __mmask8 q1, __mmask8 q2, __mmask8 q3) {
  x = _mm512_mask_mul_pd(x, q1, x, _mm512_set1_pd(0.25));
  x = _mm512_mask_mul_pd(x, q2, x, _mm512_set1_pd(0.5));
  return _mm512_mask_mul_pd(x, q3, x, _mm512_set1_pd(0.75));
}

// The codes of bars [i, i + count) of a row (count <= 8; the other lanes 0), as the factors
// code / 4, and the lanes whose code is not 0.
inline __m512d code_factors(const std::uint8_t* code, std::int64_t count, __mmask8& present) {
  std::uint64_t bits = 0;
  if (count >= 8)
    std::memcpy(&bits, code, 8);
  else
    std::memcpy(&bits, code, static_cast<std::size_t>(count));
  const __m256i c32 = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(static_cast<long long>(bits)));
  present = static_cast<__mmask8>(
      _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(c32, _mm256_setzero_si256()))));
  return _mm512_mul_pd(_mm512_cvtepi32_pd(c32), _mm512_set1_pd(0.25));
}

#pragma GCC diagnostic pop

} // namespace ldem
#endif
