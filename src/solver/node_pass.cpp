#include "solver/node_pass.hpp"

#include "solver/intact_spring.hpp"

#include <algorithm>
#include <cmath>
#include <omp.h>
#include <type_traits>

namespace ldem {

namespace {

// What the node kernel reads and writes besides the links: every node's u_n (by slot), the
// row's own, the row's forces (scratch rows, when the kernel does not integrate), and for the
// node update in the kernel u_{n-1} (overwritten by u_{n+1}), 1 / m, the held DOF and the
// integration's constants.
struct NodeRowArgs {
  const double *ux_all, *uy_all, *uz_all, *ux, *uy, *uz;
  double *fx, *fy, *fz, *wx, *wy, *wz;
  const double* im;
  const DofMask* held;
  double dt, c1, c2, inv_dt;
  double* fs; // one more scratch row (the portable kernel's running sums of s)
  const double* m; // the masses (a damped update's dissipation)
  double alpha_dt; // alpha dt of the damping
};

// The links of a row that mix the two ways: per link, whether it is fast, where the bar pass put
// its bars' forces, and of a fast link the nodes [lo, hi) whose bars the bar pass computed all
// the same (its bar row's damaged span; kRowFastAround).
struct MixedLinks {
  const double* s[kMaxRowLinks];
  std::int64_t lo[kMaxRowLinks], hi[kMaxRowLinks];
  bool fast[kMaxRowLinks];
};

// The forces on the nodes [0, n) of a row: f_i = sum over the links, in link order, of
// s (r0 + (u_other - u_i)). Without Integrate they go to the scratch rows fx, fy, fz for i in
// [0, n rounded up to 8). Returns the largest (l / l_p)^2 of the fast links' bars whose first
// nodes are the row's (0 if none).
//
// A fast link (all of them with AllFast, else those `mixed` marks) computes s with the
// operations of the bar pass's intact kernel; the others read it from the bar pass's buffer.
// From a bar's second node the relative displacement and the reference vector are exactly
// minus those from its first (a difference and a sum negate exactly), so l^2 and s are the
// same bits at both ends, and the same as the bar pass would have written to the buffer: every
// force sum is the same bits whichever way each link is taken. Vectors of 8 nodes inside
// [lo, hi) have every link on every lane and no end bar to scale; the others mask their lanes.
#if defined(__AVX512F__)
#pragma GCC diagnostic push
// GCC 12's AVX-512 headers: the same false alarms as at intact_row_kernel, here also as
// -Wuninitialized (_mm512_setzero_pd, _mm512_maskz_mov_pd).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
//
// PlaneY: a body in plane strain along y (every node's y held, u_y = 0 everywhere): the y
// components are left out, with the same bits. A neighbour's relative y is 0 - 0 = +0, so the
// bar's y is the reference's r_y exactly; the y force sums are not needed (the DOF is held);
// the held y update stores u_y = 0 (already in w, the u_{n-1} it replaces) and adds +0 to the
// motion's and the damping's squares, which leaves their sums as they are.
template <int NL, bool AllFast, bool Edge, bool Shaped, bool Integrate, bool Held, bool Energy,
          bool Damped, bool PlaneY = false>
inline void node_vector(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                        const EdgeLanes* lanes, std::int64_t i, const NodeRowArgs& a, __m512d& top,
                        __m512d& moved, __m512d* energy, __m512d& damped) {
  static_assert(!PlaneY || (Integrate && Held), "plane strain along y: nodes moved, y held");
  const __m512d ax = _mm512_load_pd(a.ux + i),
                ay = PlaneY ? _mm512_setzero_pd() : _mm512_load_pd(a.uy + i),
                az = _mm512_load_pd(a.uz + i);
  __m512d gx = _mm512_setzero_pd(), gy = _mm512_setzero_pd(), gz = _mm512_setzero_pd();
#pragma GCC unroll 14
  for (int l = 0; l < NL; ++l) {
    const LinkConst& L = c[l];
    const __mmask8 m = Edge ? lanes[l].has : 0xFF;
    const auto load = [m](const double* p) {
      return Edge ? _mm512_maskz_loadu_pd(m, p) : _mm512_loadu_pd(p);
    };
    const std::int64_t o = ref[l].other + i;
    const __m512d ux = _mm512_sub_pd(load(a.ux_all + o), ax),
                  uy = PlaneY ? _mm512_setzero_pd() : _mm512_sub_pd(load(a.uy_all + o), ay),
                  uz = _mm512_sub_pd(load(a.uz_all + o), az);
    const __m512d dx = _mm512_add_pd(_mm512_set1_pd(L.rx), ux),
                  dy = PlaneY ? _mm512_set1_pd(L.ry) : _mm512_add_pd(_mm512_set1_pd(L.ry), uy),
                  dz = _mm512_add_pd(_mm512_set1_pd(L.rz), uz);
    __m512d s;
    if (AllFast || mixed->fast[l]) {
      // The lanes whose bars lie in their row's damaged span: s from the bar pass, not measured
      // nor summed here.
      __mmask8 span = 0;
      if constexpr (!AllFast)
        if (i < mixed->hi[l] && i + 8 > mixed->lo[l])
          span = lanes_in(i, mixed->lo[l], mixed->hi[l]);
      // As intact_row_kernel: s = k - k l0 / l.
      const __m512d l2 = _mm512_fmadd_pd(dx, dx, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dz, dz)));
      const __m512d y = inv_sqrt(l2);
      s = _mm512_fnmadd_pd(_mm512_set1_pd(L.kl0), y, _mm512_set1_pd(L.k));
      // A report step's elastic energy of the bars whose first nodes are the row's, as the
      // intact kernel sums it: the same vectors of the same bar row, from u = u_b - u_a.
      // A shaped body's bars with area factors below 1 (the lanes q1, q2, q3; none in a box).
      if constexpr (Energy)
        if (L.first_node) {
          __m512d w = end_weights(Edge ? lanes[l].first | lanes[l].last : 0, L.scale);
          if constexpr (Edge && Shaped)
            w = times_quarters(w, lanes[l].q1, lanes[l].q2, lanes[l].q3);
          energy[l] = add_intact_energy(energy[l], ux, uy, uz, Vec3{L.rx, L.ry, L.rz}, l2, y, L.l0,
                                        static_cast<__mmask8>(m & ~span), w);
        }
      if constexpr (Edge) {
        // The bar row's first and last bars (node i = ilo and ihi - 1) carry their own factor;
        // a shaped body's carry theirs in the quarters (its lanes' first and last are empty).
        if constexpr (Shaped) {
          s = times_quarters(s, lanes[l].q1, lanes[l].q2, lanes[l].q3);
        } else {
          const __m512d sc = _mm512_set1_pd(L.scale);
          s = _mm512_mask_mul_pd(s, lanes[l].first, s, sc);
          s = _mm512_mask_mul_pd(s, lanes[l].last, s, sc);
        }
        s = _mm512_maskz_mov_pd(m, s);
        if (L.first_node)
          top = _mm512_mask_max_pd(top, static_cast<__mmask8>(m & ~span), top,
                                   _mm512_mul_pd(l2, _mm512_set1_pd(L.inv_lp2)));
      } else if (L.first_node) {
        if (span)
          top = _mm512_mask_max_pd(top, static_cast<__mmask8>(~span), top,
                                   _mm512_mul_pd(l2, _mm512_set1_pd(L.inv_lp2)));
        else
          top = _mm512_max_pd(top, _mm512_mul_pd(l2, _mm512_set1_pd(L.inv_lp2)));
      }
      if constexpr (!AllFast)
        if (span)
          s = _mm512_mask_loadu_pd(s, static_cast<__mmask8>(span & m), mixed->s[l] + i);
    } else {
      s = load(mixed->s[l] + i);
    }
    gx = _mm512_fmadd_pd(s, dx, gx);
    if constexpr (!PlaneY)
      gy = _mm512_fmadd_pd(s, dy, gy);
    gz = _mm512_fmadd_pd(s, dz, gz);
  }
  if constexpr (Integrate) {
    // integrate_row's update without loads or sums, with its operations in its order (its
    // damping is in c1 and c2). Damped: also the power of the damping forces, summed per lane
    // into `damped`, alpha dt m v_n^2 with v_n = (v_{n-1/2} + v_{n+1/2}) / 2 of the free DOF.
    const __m512d im = _mm512_load_pd(a.im + i);
    const __m512d inv_dt = _mm512_set1_pd(a.inv_dt), c1 = _mm512_set1_pd(a.c1),
                  c2 = _mm512_set1_pd(a.c2), dt = _mm512_set1_pd(a.dt);
    __m512i bits = _mm512_setzero_si512();
    if constexpr (Held)
      bits = _mm512_cvtepu8_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(a.held + i)));
    const __m512d half = _mm512_set1_pd(0.5);
    const auto update = [&](double* w, __m512d u, __m512d g, long long dof, __m512d& mid) {
      const __m512d o = _mm512_mul_pd(_mm512_sub_pd(u, _mm512_load_pd(w + i)), inv_dt);
      __m512d v = _mm512_add_pd(_mm512_mul_pd(c1, o), _mm512_mul_pd(_mm512_mul_pd(c2, g), im));
      __m512d k = half;
      if constexpr (Held) {
        const __mmask8 free = _mm512_testn_epi64_mask(bits, _mm512_set1_epi64(dof));
        const __m512d f = _mm512_mask_blend_pd(free, _mm512_setzero_pd(), _mm512_set1_pd(1.0));
        v = _mm512_mul_pd(f, v);
        k = _mm512_mul_pd(half, f);
      }
      const __m512d e = _mm512_add_pd(u, _mm512_mul_pd(dt, v));
      _mm512_store_pd(w + i, e);
      if constexpr (Damped)
        mid = _mm512_mul_pd(k, _mm512_add_pd(o, v));
      return _mm512_sub_pd(e, u);
    };
    __m512d mx, my = _mm512_setzero_pd(), mz;
    const __m512d qx = update(a.wx, ax, gx, kDofX, mx),
                  qy = PlaneY ? _mm512_setzero_pd() : update(a.wy, ay, gy, kDofY, my),
                  qz = update(a.wz, az, gz, kDofZ, mz);
    // (PlaneY: x^2 + (+0) is x^2, so the sums without their y terms.)
    const __m512d q2 = PlaneY ? _mm512_mul_pd(qx, qx)
                              : _mm512_add_pd(_mm512_mul_pd(qx, qx), _mm512_mul_pd(qy, qy));
    moved = _mm512_max_pd(moved, _mm512_add_pd(q2, _mm512_mul_pd(qz, qz)));
    if constexpr (Damped) {
      const __m512d m2 = PlaneY ? _mm512_mul_pd(mx, mx)
                                : _mm512_add_pd(_mm512_mul_pd(mx, mx), _mm512_mul_pd(my, my));
      const __m512d v2 = _mm512_add_pd(m2, _mm512_mul_pd(mz, mz));
      damped = _mm512_add_pd(
          damped,
          _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(a.alpha_dt), _mm512_load_pd(a.m + i)), v2));
    }
  } else {
    _mm512_store_pd(a.fx + i, gx);
    _mm512_store_pd(a.fy + i, gy);
    _mm512_store_pd(a.fz + i, gz);
  }
}

// With Integrate, the row's u_{n+1} too (into w) and its largest motion |u_{n+1} - u_n|^2
// into `moved` (the spare slots of the row hold zeros, and move by 0).
// With Energy, also the sum over the row of w (l - l0)^2 of each fast link's bars whose first
// nodes are the row's, into energy[l] (see add_intact_energy).
// Only the vectors [from, to) are taken (RowKind); without Integrate the others' forces are 0.
// `shaped`: the lanes carry a shaped body's area factors (EdgeLanes::q1, q2, q3), and a vector
// without a present bar on any link is skipped.
template <int NL, bool AllFast, bool Integrate, bool Held, bool Energy, bool Damped,
          bool PlaneY = false>
double node_row_forces(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                       const EdgeLanes* lanes, std::int64_t n, std::int64_t lo, std::int64_t hi,
                       std::int64_t from, std::int64_t to, bool shaped, const NodeRowArgs& a,
                       double& moved, double* energy, double& damped) {
  __m512d top = _mm512_setzero_pd();
  __m512d q = _mm512_setzero_pd(), dsum = _mm512_setzero_pd();
  __m512d sums[NL];
  if constexpr (Energy)
    for (int l = 0; l < NL; ++l)
      sums[l] = _mm512_setzero_pd();
  if constexpr (!Integrate)
    for (std::int64_t i = 0; i < n; i += 8)
      if (i < from || i >= to) {
        _mm512_store_pd(a.fx + i, _mm512_setzero_pd());
        _mm512_store_pd(a.fy + i, _mm512_setzero_pd());
        _mm512_store_pd(a.fz + i, _mm512_setzero_pd());
      }
  for (std::int64_t i = from; i < to; i += 8) {
    if (i >= lo && i + 8 <= hi) {
      node_vector<NL, AllFast, false, false, Integrate, Held, Energy, Damped, PlaneY>(
          c, ref, mixed, lanes, i, a, top, q, sums, dsum);
    } else {
      // (A vector of a shaped body's absent nodes, which no present bar reaches, has nothing
      // to gather, and its held nodes stay where they are.)
      std::uint8_t any = 0xFF;
      if (shaped) {
        any = 0;
        for (int l = 0; l < NL; ++l)
          any |= lanes[l].has;
      }
      if (!shaped)
        node_vector<NL, AllFast, true, false, Integrate, Held, Energy, Damped, PlaneY>(
            c, ref, mixed, lanes, i, a, top, q, sums, dsum);
      else if (any != 0)
        node_vector<NL, AllFast, true, true, Integrate, Held, Energy, Damped, PlaneY>(
            c, ref, mixed, lanes, i, a, top, q, sums, dsum);
      else if constexpr (!Integrate) {
        _mm512_store_pd(a.fx + i, _mm512_setzero_pd());
        _mm512_store_pd(a.fy + i, _mm512_setzero_pd());
        _mm512_store_pd(a.fz + i, _mm512_setzero_pd());
      }
      lanes += kMaxRowLinks;
    }
  }
  if constexpr (Energy)
    for (int l = 0; l < NL; ++l)
      energy[l] = _mm512_reduce_add_pd(sums[l]);
  moved = _mm512_reduce_max_pd(q);
  if constexpr (Damped)
    damped = _mm512_reduce_add_pd(dsum);
  return _mm512_reduce_max_pd(top);
}
#pragma GCC diagnostic pop
#else
// Without AVX-512 (where the fast path is off: SolverOptions::intact_at_nodes). Inside
// [lo, hi), where every node has every link, the links in chunks of four over the whole range
// (GCC vectorises each chunk; a single pass over 14 links would need more pointers than there
// are registers), as sum s (r0 + u_other) - u_i sum s, two operations fewer per link than the
// sum of s (r0 + (u_other - u_i)) taken link by link outside it. A fast link, should one be
// asked for, computes s as the portable intact kernel does, and makes the row go link by link.
// The node update is integrate_row's.
template <int B, int E, bool First, bool Last>
void portable_chunk(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                    std::int64_t lo, std::int64_t hi, const NodeRowArgs& a, double* fs) {
  constexpr int N = E - B;
  const double *s_[N], *x_[N], *y_[N], *z_[N];
  double rx_[N], ry_[N], rz_[N];
  for (int l = 0; l < N; ++l) {
    s_[l] = mixed->s[B + l];
    x_[l] = a.ux_all + ref[B + l].other;
    y_[l] = a.uy_all + ref[B + l].other;
    z_[l] = a.uz_all + ref[B + l].other;
    rx_[l] = c[B + l].rx;
    ry_[l] = c[B + l].ry;
    rz_[l] = c[B + l].rz;
  }
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  const double* __restrict ux = a.ux;
  const double* __restrict uy = a.uy;
  const double* __restrict uz = a.uz;
#pragma omp simd
  for (std::int64_t i = lo; i < hi; ++i) {
    double gx = First ? 0.0 : fx[i], gy = First ? 0.0 : fy[i], gz = First ? 0.0 : fz[i],
           st = First ? 0.0 : fs[i];
#pragma GCC unroll 4
    for (int l = 0; l < N; ++l) {
      const double t = s_[l][i];
      gx += t * (rx_[l] + x_[l][i]);
      gy += t * (ry_[l] + y_[l][i]);
      gz += t * (rz_[l] + z_[l][i]);
      st += t;
    }
    if constexpr (Last) {
      fx[i] = gx - st * ux[i];
      fy[i] = gy - st * uy[i];
      fz[i] = gz - st * uz[i];
    } else {
      fx[i] = gx;
      fy[i] = gy;
      fz[i] = gz;
      fs[i] = st;
    }
  }
}

template <int NL, bool AllFast, bool Integrate, bool Held, bool Energy, bool Damped,
          bool PlaneY = false>
double node_row_forces(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                       const EdgeLanes*, std::int64_t n, std::int64_t lo, std::int64_t hi,
                       std::int64_t, std::int64_t, bool, const NodeRowArgs& a, double&, double*,
                       double&) {
  static_assert(!Integrate, "the portable kernel gives forces only");
  bool any_fast = AllFast;
  for (int l = 0; l < NL; ++l)
    any_fast = any_fast || mixed->fast[l];
  if (any_fast)
    lo = hi = 0;
  if (hi > lo) {
    constexpr int C = 4;
    auto chunk = [&]<int B>(auto self, std::integral_constant<int, B>) {
      constexpr int E = B + C < NL ? B + C : NL;
      portable_chunk<B, E, B == 0, E == NL>(c, ref, mixed, lo, hi, a, a.fs);
      if constexpr (E < NL)
        self(self, std::integral_constant<int, E>{});
    };
    chunk(chunk, std::integral_constant<int, 0>{});
  }
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  const double* __restrict ux = a.ux;
  const double* __restrict uy = a.uy;
  const double* __restrict uz = a.uz;
  for (const auto& [e0, e1] : {std::pair{std::int64_t{0}, lo}, std::pair{hi, n}})
    for (std::int64_t i = e0; i < e1; ++i)
      fx[i] = fy[i] = fz[i] = 0.0;
  double top = 0.0;
  for (int l = 0; l < NL; ++l) {
    const LinkConst& L = c[l];
    const double* __restrict ox = a.ux_all + ref[l].other;
    const double* __restrict oy = a.uy_all + ref[l].other;
    const double* __restrict oz = a.uz_all + ref[l].other;
    const bool fast = AllFast || mixed->fast[l];
    const double* __restrict sb = fast ? nullptr : mixed->s[l];
    for (const auto& [e0, e1] :
         {std::pair{L.ilo, std::min(L.ihi, lo)}, std::pair{std::max(L.ilo, hi), L.ihi}}) {
#pragma omp simd reduction(max : top)
      for (std::int64_t i = e0; i < e1; ++i) {
        const double dx = L.rx + (ox[i] - ux[i]), dy = L.ry + (oy[i] - uy[i]),
                     dz = L.rz + (oz[i] - uz[i]);
        double s;
        if (fast) {
          const double l2 = dx * dx + dy * dy + dz * dz;
          s = L.k - L.kl0 / std::sqrt(l2);
          if (i == L.ilo)
            s *= L.scale;
          if (i == L.ihi - 1)
            s *= L.scale;
          if (L.first_node)
            top = std::max(top, l2 * L.inv_lp2);
        } else {
          s = sb[i];
        }
        fx[i] += s * dx;
        fy[i] += s * dy;
        fz[i] += s * dz;
      }
    }
  }
  return top;
}
#endif

} // namespace

// ---------------------------------------------------------------------------------------
// Node pass: gather, integrate, and the per-row sums the energy balance needs.

namespace {

struct IntegrationConstants {
  double dt, c1, c2, alpha;
};

// v_{n+1/2} and u_{n+1} of one row of nodes from the gathered forces, and (with Sums) the
// row's contributions to the energy ledger. A separate function so that every array is a
// __restrict parameter: GCC then vectorises the loop.
template <bool Damped, bool Loads, bool Report, bool Held, bool Motion>
inline void integrate_row(index_t n, const IntegrationConstants& c, const double* __restrict free_x,
                          const double* __restrict free_y, const double* __restrict free_z,
                          const double* __restrict im, const double* __restrict m,
                          double* __restrict fx, double* __restrict fy, double* __restrict fz,
                          double* __restrict fw, const double* __restrict px,
                          const double* __restrict py, const double* __restrict pz,
                          const double* __restrict ux, const double* __restrict uy,
                          const double* __restrict uz, double* __restrict wx, double* __restrict wy,
                          double* __restrict wz, double* __restrict fd, double& damping,
                          double& load_mid, double& load_half, double& kinetic, double& motion) {
  const double dt = c.dt, c1 = c.c1, c2 = c.c2, alpha = c.alpha, inv_dt = 1.0 / c.dt;
  constexpr bool sums = Damped || Loads || Report;
  // No reduction clause: with one, GCC 12 does not vectorise the loop. The per-node terms of
  // the sums go to the scratch rows (fx.. are free once read) and are added afterwards.
#pragma omp simd
  for (index_t i = 0; i < n; ++i) {
    // 1 on a free DOF, 0 on a held one; a row without held DOF reads no factors.
    const double kx = Held ? free_x[i] : 1.0;
    const double ky = Held ? free_y[i] : 1.0;
    const double kz = Held ? free_z[i] : 1.0;
    const double gx = Loads ? fx[i] + px[i] : fx[i];
    const double gy = Loads ? fy[i] + py[i] : fy[i];
    const double gz = Loads ? fz[i] + pz[i] : fz[i];
    // u_{n-1} is read from w and u_{n+1} written over it: v_{n-1/2} = (u_n - u_{n-1}) / dt.
    const double ox = (ux[i] - wx[i]) * inv_dt, oy = (uy[i] - wy[i]) * inv_dt,
                 oz = (uz[i] - wz[i]) * inv_dt;
    const double nx = kx * (c1 * ox + c2 * gx * im[i]);
    const double ny = ky * (c1 * oy + c2 * gy * im[i]);
    const double nz = kz * (c1 * oz + c2 * gz * im[i]);
    const double ex = ux[i] + dt * nx, ey = uy[i] + dt * ny, ez = uz[i] + dt * nz;
    wx[i] = ex;
    wy[i] = ey;
    wz[i] = ez;
    if constexpr (Motion) {
      // The node's motion in this step, |u_{n+1} - u_n|^2 (bar_row_stays_intact).
      const double qx = ex - ux[i], qy = ey - uy[i], qz = ez - uz[i];
      fd[i] = qx * qx + qy * qy + qz * qz;
    }
    if constexpr (sums) {
      // Mid-step velocity v_n = (v_{n-1/2} + v_{n+1/2}) / 2 of the free DOF.
      const double mx = 0.5 * kx * (ox + nx), my = 0.5 * ky * (oy + ny), mz = 0.5 * kz * (oz + nz);
      fx[i] = Damped ? alpha * dt * m[i] * (mx * mx + my * my + mz * mz) : 0.0;
      fy[i] = Loads ? dt * (px[i] * mx + py[i] * my + pz[i] * mz) : 0.0;
      // Central-difference kinetic energy m v_{n-1/2} . v_{n+1/2} / 2: with it the discrete
      // balance is exact for linear elastic motion (see docs/model.md); m v_n^2 / 2 would be
      // off by O((omega dt)^2) for the fast modes a crack excites.
      fz[i] = Report ? 0.5 * m[i] * (kx * ox * nx + ky * oy * ny + kz * oz * nz) : 0.0;
      fw[i] =
          Report && Loads ? 0.5 * dt * (kx * px[i] * ox + ky * py[i] * oy + kz * pz[i] * oz) : 0.0;
    }
  }
  if constexpr (Motion) {
    double top = 0.0;
#pragma omp simd reduction(max : top)
    for (index_t i = 0; i < n; ++i)
      top = std::max(top, fd[i]);
    motion = std::sqrt(top);
  }
  // Each sum in node order, and only those that are not zero by the template's terms.
  damping = load_mid = load_half = kinetic = 0.0;
  if constexpr (Damped)
    for (index_t i = 0; i < n; ++i)
      damping += fx[i];
  if constexpr (Loads)
    for (index_t i = 0; i < n; ++i)
      load_mid += fy[i];
  if constexpr (Report)
    for (index_t i = 0; i < n; ++i)
      kinetic += fz[i];
  if constexpr (Report && Loads)
    for (index_t i = 0; i < n; ++i)
      load_half += fw[i];
}

} // namespace

// (The node kernel is inlined here: GCC 12's AVX-512 headers' false alarms again, see
// node_vector.)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
template <bool Damped, bool Loads, bool Report>
void node_rows_range(SimulationCore& core, std::size_t line, const double* s_plane,
                     const double* s_below) {
  const std::size_t begin = core.layout.lines[line].node_begin,
                    end = core.layout.lines[line].node_end;
  // The lines whose bars the line's nodes end: (j, k), (j - 1, k), and the same in plane k - 1.
  const std::size_t per_plane = core.lat.ny() + 1ull;
  const std::size_t j = line % per_plane, k = line / per_plane;
  const bool lines_fast =
      core.fast_path && core.line_fast[line] && (j == 0 || core.line_fast[line - 1]) &&
      (k == 0 ||
       (core.line_fast[line - per_plane] && (j == 0 || core.line_fast[line - per_plane - 1])));
  // The largest (l / l_p)^2 of the fast bars whose first nodes are the corner and the centre
  // row's.
  double top_row[2] = {0.0, 0.0};
  const double dt = core.dt;
  const double half = 0.5 * core.opt.damping * dt;
  const double c1 = (1.0 - half) / (1.0 + half), c2 = dt / (1.0 + half);
  const double alpha = core.opt.damping;
  {
    double* __restrict fx =
        core.thread_scratch[static_cast<std::size_t>(omp_get_thread_num())].data();
    double* __restrict fy = fx + core.scratch_stride;
    double* __restrict fz = fy + core.scratch_stride;
    double* __restrict fw = fz + core.scratch_stride;
    // The held DOF of a row as factors 1 (free) and 0 (held): the node update then reads only
    // doubles, which GCC vectorises (with the mask's bytes in the loop it does not).
    double* __restrict free_x = fw + core.scratch_stride;
    double* __restrict free_y = free_x + core.scratch_stride;
    double* __restrict free_z = free_y + core.scratch_stride;
    double* __restrict fd = free_z + core.scratch_stride;
    for (std::size_t r = begin; r < end; ++r) {
      const NodeRow& row = core.layout.node_rows[r];
      const index_t n = row.length;
      const auto n0 = static_cast<std::size_t>(core.layout.row_origin[r]);
      const double* __restrict ux = core.ux.data() + n0;
      const double* __restrict uy = core.uy.data() + n0;
      const double* __restrict uz = core.uz.data() + n0;
      // A shaped body's rows have their own vectors with lane masks (the AVX-512 kernel's) and
      // nodes that move, [from, to); their links are the kind's. (The portable kernel reads the
      // absent bars' s = 0 from the buffers and keeps the kind's ranges: the box's, whose
      // arithmetic a full mask then repeats bit for bit.)
      const RowKind& span = core.layout.coded() ? core.layout.row_span[r]
                                                : core.layout.row_kinds[core.layout.row_kind[r]];
      const RowKind& kind = kVectorKernel ? span : core.layout.row_kinds[core.layout.row_kind[r]];
      const auto from = static_cast<index_t>(span.from),
                 to = static_cast<index_t>(std::min<std::int64_t>(span.to, n));
      // The integration below streams u_{n-1} (overwritten by u_{n+1}) and 1/m from memory; ask for
      // them now so that they arrive while the row's forces are gathered (measured: +9 % on 64^3).
      for (index_t i = from; i < to; i += 8) {
        __builtin_prefetch(core.wx.data() + n0 + i, 1);
        __builtin_prefetch(core.wy.data() + n0 + i, 1);
        __builtin_prefetch(core.wz.data() + n0 + i, 1);
        __builtin_prefetch(core.inv_mass.data() + n0 + i, 0);
      }
      // The portable kernel takes a whole row in one pass where it can (core.layout.row_whole).
      const std::int64_t lo = !kVectorKernel && core.layout.row_whole[r] ? 0 : kind.lo;
      const std::int64_t hi =
          !kVectorKernel && core.layout.row_whole[r] ? std::int64_t{n} : kind.hi;
      const LinkConst* lc = &core.layout.link_const[kMaxRowLinks * core.layout.row_kind[r]];
      const LinkRef* ref = &core.layout.link_ref[kMaxRowLinks * r];
      // Of the rows the links read, the one farthest on in memory (in the plane above) is the
      // only one no earlier row has read: ask for it now too, or each of its vectors waits for
      // memory inside the gather (measured: +18 % on a 96^3 prism, +24 % on its cylinder).
      if (kind.links > 0) {
        std::int64_t ahead = ref[0].other;
        for (int l = 1; l < kind.links; ++l)
          ahead = std::max(ahead, ref[l].other);
        const std::int64_t stop =
            std::min<std::int64_t>(to, static_cast<std::int64_t>(core.ux.size()) - ahead);
        for (std::int64_t i = std::max<std::int64_t>(from, -ahead); i < stop; i += 8) {
          __builtin_prefetch(core.ux.data() + ahead + i, 0);
          __builtin_prefetch(core.uy.data() + ahead + i, 0);
          __builtin_prefetch(core.uz.data() + ahead + i, 0);
        }
      }

      const int nl = kind.links;
      // Each link fast or from the buffer, as its bar row is in this step. Rows inside a box
      // have 14 links, rows on its faces and edges fewer; a row with fewer than 7 (the corner
      // rows along the x edges) has links that no node has up to 7, which every lane masks.
      // (A row's links are all fast when the four lines are, else look link by link.)
      bool all_fast = nl >= 7 && lines_fast;
      if (!all_fast && nl >= 7 && core.fast_path) {
        all_fast = true;
        for (int l = 0; l < nl; ++l)
          all_fast = all_fast && core.row_fast[ref[l].bar_row] == kRowFast;
      }
      MixedLinks mixed;
      if (!all_fast)
        for (int l = 0; l < kMaxRowLinks; ++l) {
          const std::uint8_t way =
              core.fast_path && l < nl ? core.row_fast[ref[l].bar_row] : kRowByPass;
          mixed.fast[l] = way != kRowByPass;
          mixed.s[l] = (lc[l].dk == 0 ? s_plane : s_below) + ref[l].plane_base;
          mixed.lo[l] = mixed.hi[l] = 0;
          if (way == kRowFastAround) {
            // The span's bars [a, b) of the bar row are the nodes [a - d, b - d) here: node i's
            // bar is bar i + d of its row (plane_base: where node 0's bar's force would be).
            const BarRow& br = core.layout.bar_rows[ref[l].bar_row];
            const FamilyInfo& fi = core.lat.family(br.family);
            const std::int64_t d =
                ref[l].plane_base -
                static_cast<std::int64_t>(fi.plane_offset + std::size_t{fi.plane_stride} * br.j);
            const auto [a, b] = core.damaged_span[ref[l].bar_row];
            mixed.lo[l] = a - d;
            mixed.hi[l] = b - d;
          }
        }
      const int padded = std::max(nl, 7);
      double* __restrict wx = core.wx.data() + n0;
      double* __restrict wy = core.wy.data() + n0;
      double* __restrict wz = core.wz.data() + n0;
      const double* __restrict im = core.inv_mass.data() + n0;
      const DofMask* __restrict held = core.held.data() + n0;
      const NodeRowArgs args{core.ux.data(),
                             core.uy.data(),
                             core.uz.data(),
                             ux,
                             uy,
                             uz,
                             fx,
                             fy,
                             fz,
                             wx,
                             wy,
                             wz,
                             im,
                             held,
                             dt,
                             c1,
                             c2,
                             1.0 / dt,
                             fw,
                             core.mass.data() + n0,
                             alpha * dt};
      // (A row whose nodes no load or platen touches takes the update without loads: the same
      // bits, its loads being zeros.)
      const bool loaded = core.row_loaded.empty() || core.row_loaded[r] != 0;
      // On a step that reports nothing the kernel also moves the row's nodes (what
      // integrate_row would do, the same bits; with damping it sums the damping's dissipation
      // per lane, integrate_row node by node), unless imposed velocities need its forces or
      // loads act on the row.
      const bool in_kernel =
          kVectorKernel && !Report && core.bc.imposed_row[r] < 0 && !(Loads && loaded);
      double motion = 0.0, damped = 0.0;
      double energy[kMaxRowLinks];
      const auto forces = [&](auto count, auto fast, auto integrate, auto held_c, auto plane_c) {
        constexpr bool I = decltype(integrate)::value;
        constexpr bool D = Damped && I;
        return node_row_forces < decltype(count)::value, decltype(fast)::value, I,
               decltype(held_c)::value, Report && kVectorKernel, D,
               decltype(plane_c)::value >
                   (lc, ref, &mixed, core.layout.edge_lanes.data() + kind.edge_begin, n, lo, hi,
                    span.from, span.to, core.layout.coded(), args, motion, energy, damped);
      };
      const auto by_count = [&](auto... flags) {
        switch (padded) {
        case 14:
          return forces(std::integral_constant<int, 14>{}, flags...);
        case 13:
          return forces(std::integral_constant<int, 13>{}, flags...);
        case 12:
          return forces(std::integral_constant<int, 12>{}, flags...);
        case 11:
          return forces(std::integral_constant<int, 11>{}, flags...);
        case 10:
          return forces(std::integral_constant<int, 10>{}, flags...);
        case 9:
          return forces(std::integral_constant<int, 9>{}, flags...);
        case 8:
          return forces(std::integral_constant<int, 8>{}, flags...);
        default:
          return forces(std::integral_constant<int, 7>{}, flags...);
        }
      };
      using yes = std::true_type;
      using no = std::false_type;
      double top = 0.0;
      if constexpr (kVectorKernel && !Report) {
        if (in_kernel) {
          if (core.plane_y) // (every node's y held)
            top = all_fast ? by_count(yes{}, yes{}, yes{}, yes{})
                           : by_count(no{}, yes{}, yes{}, yes{});
          else if (core.row_held[r])
            top =
                all_fast ? by_count(yes{}, yes{}, yes{}, no{}) : by_count(no{}, yes{}, yes{}, no{});
          else
            top = all_fast ? by_count(yes{}, yes{}, no{}, no{}) : by_count(no{}, yes{}, no{}, no{});
        }
      }
      if (!in_kernel)
        top = all_fast ? by_count(yes{}, no{}, no{}, no{}) : by_count(no{}, no{}, no{}, no{});
      // The fast bar rows whose first nodes are this row's: their elastic energy, U = k (l -
      // l0)^2 / 2 with the area factors in the weights (as bar_rows has it for the others).
      // (A row with a damaged span adds them to its span's, which the bar pass gave.)
      if constexpr (Report && kVectorKernel)
        for (int l = 0; l < nl; ++l) {
          const std::size_t b = ref[l].bar_row;
          if (lc[l].first_node && core.row_fast[b] != kRowByPass) {
            const double u = 0.5 * lc[l].k * energy[l];
            core.energy_rows_u[b] =
                core.row_fast[b] == kRowFastAround ? core.energy_rows_u[b] + u : u;
          }
        }
      top_row[row.centre] = top;
      if (in_kernel) {
        core.node_row_motion[r] = std::sqrt(motion);
        core.row_damping[r] = damped;
        core.row_load_mid[r] = core.row_load_half[r] = core.row_kinetic[r] = 0.0;
        continue;
      }
      // A row with imposed-velocity nodes keeps its gathered forces for apply_velocities.
      if (const std::int64_t o = core.bc.imposed_row[r]; o >= 0) {
        double* kept = core.bc.imposed_force.data() + o;
        std::copy(fx, fx + n, kept);
        std::copy(fy, fy + n, kept + n);
        std::copy(fz, fz + n, kept + 2 * n);
      }
      const double* __restrict m = core.mass.data() + n0;
      const double* __restrict px = Loads ? core.px.data() + n0 : nullptr;
      const double* __restrict py = Loads ? core.py.data() + n0 : nullptr;
      const double* __restrict pz = Loads ? core.pz.data() + n0 : nullptr;
      double damping = 0.0, load_mid = 0.0, load_half = 0.0, kinetic = 0.0;
      const IntegrationConstants ic{dt, c1, c2, alpha};
      // (The rows' motion only matters to the fast path.)
      // (The nodes [from, to): the others' terms of the sums are zeros, which change no sum.)
      const auto integrate = [&](auto held_c, auto motion_c) {
        constexpr bool H = decltype(held_c)::value, M = decltype(motion_c)::value;
        const index_t f = from;
        const auto at = [f](const double* p) { return p ? p + f : p; };
        if constexpr (Loads)
          if (!loaded) {
            integrate_row<Damped, false, Report, H, M>(
                to - from, ic, H ? free_x + f : nullptr, H ? free_y + f : nullptr,
                H ? free_z + f : nullptr, im + f, m + f, fx + f, fy + f, fz + f, fw + f, nullptr,
                nullptr, nullptr, ux + f, uy + f, uz + f, wx + f, wy + f, wz + f, fd + f, damping,
                load_mid, load_half, kinetic, motion);
            return;
          }
        integrate_row<Damped, Loads, Report, H, M>(
            to - from, ic, H ? free_x + f : nullptr, H ? free_y + f : nullptr,
            H ? free_z + f : nullptr, im + f, m + f, fx + f, fy + f, fz + f, fw + f, at(px), at(py),
            at(pz), ux + f, uy + f, uz + f, wx + f, wy + f, wz + f, fd + f, damping, load_mid,
            load_half, kinetic, motion);
      };
      if (core.row_held[r]) {
        for (index_t i = from; i < to; ++i) {
          free_x[i] = held[i] & kDofX ? 0.0 : 1.0;
          free_y[i] = held[i] & kDofY ? 0.0 : 1.0;
          free_z[i] = held[i] & kDofZ ? 0.0 : 1.0;
        }
        core.fast_path ? integrate(yes{}, yes{}) : integrate(yes{}, no{});
      } else {
        core.fast_path ? integrate(no{}, yes{}) : integrate(no{}, no{});
      }
      core.node_row_motion[r] = motion; // (apply_velocities adds the imposed DOF's motion)
      core.row_damping[r] = damping;
      core.row_load_mid[r] = load_mid;
      core.row_load_half[r] = load_half;
      core.row_kinetic[r] = kinetic;
    }
  }
  // The line's fast bar rows, whose first nodes are its corner row's (edges) or its centre
  // row's (the rest): no bar longer than the longest the kernel saw there (relative to each
  // one's l_p), a bound for the next step's test (bar_row_stays_intact) as the intact kernel's
  // own largest length is.
  for (std::size_t r = core.layout.lines[line].bar_begin;
       core.fast_path && r < core.layout.lines[line].bar_end; ++r)
    if (core.row_fast[r] != kRowByPass)
      core.row_ratio[r] = top_row[core.layout.row_first_centre[r]];
}
#pragma GCC diagnostic pop

template void node_rows_range<false, false, false>(SimulationCore&, std::size_t, const double*,
                                                   const double*);
template void node_rows_range<false, false, true>(SimulationCore&, std::size_t, const double*,
                                                  const double*);
template void node_rows_range<false, true, false>(SimulationCore&, std::size_t, const double*,
                                                  const double*);
template void node_rows_range<false, true, true>(SimulationCore&, std::size_t, const double*,
                                                 const double*);
template void node_rows_range<true, false, false>(SimulationCore&, std::size_t, const double*,
                                                  const double*);
template void node_rows_range<true, false, true>(SimulationCore&, std::size_t, const double*,
                                                 const double*);
template void node_rows_range<true, true, false>(SimulationCore&, std::size_t, const double*,
                                                 const double*);
template void node_rows_range<true, true, true>(SimulationCore&, std::size_t, const double*,
                                                const double*);

} // namespace ldem
