#include "solver/stable_step.hpp"

#include "energy/exact_sum.hpp"
#include "util/aligned.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace ldem {

namespace {

// Undamaged axial stiffness EA / l0 of every bar (including the boundary area factor): a
// per-bar table's own array, else `own` filled from the families' (planes of bars in parallel);
// nullptr for a box of one material, whose rows of links take their stiffness from UnitLinks.
const double* bar_stiffness(const Lattice& lat, const BarTable& table, std::vector<double>& own) {
  if (table.per_bar())
    return table.k_bar().data();
  if (!lat.shaped())
    return nullptr;
  own.resize(lat.num_bars());
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    const double kf = table.family(f).k;
    const auto planes = static_cast<std::int64_t>(fi.nk);
#pragma omp parallel for schedule(static) if (std::int64_t{fi.ni} * fi.nj * fi.nk > kParallelMinItems)
    for (std::int64_t kk = 0; kk < planes; ++kk)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i)
          own[lat.bar(static_cast<Family>(f), i, j, static_cast<index_t>(kk))] =
              kf * lat.area_factor(static_cast<Family>(f), i, j, static_cast<index_t>(kk));
  }
  return own.data();
}

// A row's links with their unit vectors (each r0 / |r0|) and their bars' stiffness: `kb`'s, or
// without it (a box of one material) the family's k times the bar's area factor, which along a
// link's bars changes only at its first and last (the body's faces across x): those two and
// one for the bars between, the numbers bar_stiffness would store.
struct UnitLinks {
  RowLink links[kMaxRowLinks];
  double e[kMaxRowLinks][3];
  double k_first[kMaxRowLinks], k_inner[kMaxRowLinks], k_last[kMaxRowLinks];
  const double* kb;
  int count = 0;
  UnitLinks(const Lattice& lat, const BarTable& table, const double* kb_, const NodeRow& row)
      : kb(kb_), count(row_links(lat, row, links)) {
    for (int l = 0; l < count; ++l) {
      const RowLink& L = links[l];
      const Vec3& r = L.r0;
      const double len = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
      e[l][0] = r.x / len;
      e[l][1] = r.y / len;
      e[l][2] = r.z / len;
      if (kb || L.ihi <= L.ilo)
        continue;
      const auto k_of = [&](index_t i) {
        const BarAddress a = lat.bar_address(static_cast<index_t>(L.bar_base + i));
        return table.family(static_cast<int>(a.family)).k *
               lat.area_factor(a.family, a.i, a.j, a.k);
      };
      k_first[l] = k_of(L.ilo);
      k_last[l] = k_of(L.ihi - 1);
      k_inner[l] = L.ihi - L.ilo > 2 ? k_of(L.ilo + 1) : k_first[l];
    }
  }
  // The stiffness of the bar of link l at node i of the row.
  double k(int l, index_t i) const {
    if (kb)
      return kb[static_cast<std::size_t>(links[l].bar_base + i)];
    return i == links[l].ilo ? k_first[l] : i + 1 == links[l].ihi ? k_last[l] : k_inner[l];
  }
};

// Calls f(other node, unit vector towards it, bar stiffness) for every bar of node i of a row.
template <class F> void for_each_bar_of(index_t i, const UnitLinks& u, F&& f) {
  for (int l = 0; l < u.count; ++l) {
    const RowLink& L = u.links[l];
    if (i < L.ilo || i >= L.ihi)
      continue;
    f(static_cast<index_t>(L.other_base + i), u.e[l], u.k(l, i));
  }
}

// Largest eigenvalue of a symmetric tridiagonal matrix (diagonal a, off-diagonal b[1..m-1])
// by bisection on Sturm sequence counts.
double tridiagonal_max_eigenvalue(const std::vector<double>& a, const std::vector<double>& b) {
  const std::size_t m = a.size();
  double lo = 0.0, hi = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const double r = (i > 0 ? std::abs(b[i]) : 0.0) + (i + 1 < m ? std::abs(b[i + 1]) : 0.0);
    lo = std::min(lo, a[i] - r);
    hi = std::max(hi, a[i] + r);
  }
  auto count_below = [&](double x) { // eigenvalues < x
    int count = 0;
    double d = 1.0;
    for (std::size_t i = 0; i < m; ++i) {
      d = a[i] - x - (i > 0 ? b[i] * b[i] / d : 0.0);
      if (d == 0.0)
        d = -1e-300;
      if (d < 0.0)
        ++count;
    }
    return count;
  };
  for (int it = 0; it < 200 && hi - lo > 1e-15 * std::max(std::abs(hi), 1.0); ++it) {
    const double mid = 0.5 * (lo + hi);
    if (count_below(mid) >= static_cast<int>(m))
      hi = mid;
    else
      lo = mid;
  }
  return 0.5 * (lo + hi);
}

} // namespace

StableStep compute_stable_step(const Lattice& lat, const BarTable& table,
                               const std::vector<double>& mass,
                               const std::vector<unsigned char>& held_given,
                               const StableStepParts* parts) {
  std::vector<double> kb_own;
  const double* const kb = bar_stiffness(lat, table, kb_own);
  const std::size_t n = lat.num_nodes();
  // The rows of nodes this process owns (a row along x is never split between processes).
  std::vector<NodeRow> rows = node_rows(lat);
  if (parts)
    rows.erase(std::remove_if(rows.begin(), rows.end(),
                              [&](const NodeRow& r) { return !parts->owned[r.first]; }),
               rows.end());
  const std::int64_t nrows = static_cast<std::int64_t>(rows.size());
  // 1 / sqrt(m) and the held DOF of every node; a ghost node's from its owner.
  AlignedVector<double> rsm(n); // (large arrays: huge pages, util/aligned.hpp)
  std::vector<unsigned char> held(n, 0);
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    rsm[i] = 1.0 / std::sqrt(mass[i]);
    held[i] = held_given.empty() ? 0 : held_given[i];
  }
  if (parts) {
    std::vector<double> v(3 * n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      v[3 * i] = rsm[i];
      v[3 * i + 1] = held[i];
    }
    parts->exchange(v);
    for (std::size_t i = 0; i < n; ++i) {
      rsm[i] = v[3 * i];
      held[i] = static_cast<unsigned char>(v[3 * i + 1]);
    }
  }
  auto free_dof = [&](index_t node, int d) { return held[node] & (1u << d) ? 0.0 : 1.0; };
  // Calls f(node) for the nodes of the owned rows, row by row (threads share the rows).
  auto for_owned = [&](auto&& f) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r)
      f(rows[r]);
  };

  // y = M^-1/2 K M^-1/2 x on the owned nodes (x, y interleaved: 3 per node), gathered per node
  // from M^-1/2 x on the free DOF (a ghost node's from its owner).
  std::vector<double> scaled(3 * n, 0.0);
  auto apply = [&](const AlignedVector<double>& x, AlignedVector<double>& y) {
    for_owned([&](const NodeRow& row) {
      for (index_t i = 0; i < row.length; ++i) {
        const index_t node = row.first + i;
        for (int d = 0; d < 3; ++d)
          scaled[3 * node + d] = x[3 * node + d] * rsm[node] * free_dof(node, d);
      }
    });
    if (parts)
      parts->exchange(scaled);
    // Link by link along the row, each node's terms added in the order of its links (the
    // numbers of a loop over each node's links), into the row's sums.
    for_owned([&](const NodeRow& row) {
      const UnitLinks u(lat, table, kb, row);
      thread_local std::vector<double> acc;
      acc.assign(3 * std::size_t{row.length}, 0.0);
      const double* const s = scaled.data();
      for (int l = 0; l < u.count; ++l) {
        const RowLink& L = u.links[l];
        const double e0 = u.e[l][0], e1 = u.e[l][1], e2 = u.e[l][2];
        for (index_t i = L.ilo; i < L.ihi; ++i) {
          const std::size_t a = 3 * (std::size_t{row.first} + i),
                            b = 3 * static_cast<std::size_t>(L.other_base + i);
          double proj = 0.0;
          proj += e0 * (s[a] - s[b]);
          proj += e1 * (s[a + 1] - s[b + 1]);
          proj += e2 * (s[a + 2] - s[b + 2]);
          const double kp = u.k(l, i) * proj;
          acc[3 * i] += kp * e0;
          acc[3 * i + 1] += kp * e1;
          acc[3 * i + 2] += kp * e2;
        }
      }
      for (index_t i = 0; i < row.length; ++i) {
        const index_t node = row.first + i;
        for (int d = 0; d < 3; ++d)
          y[3 * node + d] = acc[3 * i + d] * rsm[node] * free_dof(node, d);
      }
    });
  };
  // a . b over the owned nodes: each row's products added in order along it, the rows' sums
  // exactly (and with the other processes' rows), whatever their order.
  std::vector<double> row_sums(rows.size());
  // The rows' sums in row_sums, added exactly.
  const auto sum_rows = [&] {
    // Scaled by a power of two below the largest row's sum of all processes, into the fixed
    // point's range (ExactSum is made for energies in J; these sums can reach 1e30).
    double largest = 0.0;
    for (double s : row_sums)
      largest = std::max(largest, std::abs(s));
    if (parts)
      largest = parts->max(largest);
    int e = 0;
    std::frexp(largest, &e);
    ExactSum total;
    for (double s : row_sums)
      total.add(std::ldexp(s, -e));
    if (parts)
      parts->sum(total);
    return std::ldexp(total.value(), e);
  };
  auto dot = [&](const AlignedVector<double>& a, const AlignedVector<double>& b) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      double s = 0.0;
      const std::size_t q0 = 3 * std::size_t{rows[r].first};
      for (std::size_t q = q0; q < q0 + 3 * std::size_t{rows[r].length}; ++q)
        s += a[q] * b[q];
      row_sums[r] = s;
    }
    return sum_rows();
  };

  StableStep out;
  // Gershgorin: every eigenvalue lies below the largest absolute row sum (the rows in parallel:
  // a largest value is the same whatever the order).
  double bound = 0.0;
#pragma omp parallel for schedule(static) reduction(max : bound) if (3 * n > kParallelMinItems)
  for (std::int64_t r = 0; r < nrows; ++r) {
    const NodeRow& row = rows[r];
    const UnitLinks u(lat, table, kb, row);
    for (index_t i = 0; i < row.length; ++i) {
      const index_t node = row.first + i;
      double diag[3][3] = {}, off[3] = {};
      for_each_bar_of(i, u, [&](index_t other, const double* e, double k) {
        const double eo = std::abs(e[0]) * free_dof(other, 0) +
                          std::abs(e[1]) * free_dof(other, 1) + std::abs(e[2]) * free_dof(other, 2);
        for (int p = 0; p < 3; ++p) {
          for (int q = 0; q < 3; ++q)
            diag[p][q] += k * e[p] * e[q] / mass[node] * free_dof(node, q);
          off[p] += k * std::abs(e[p]) * eo * rsm[node] * rsm[other];
        }
      });
      for (int p = 0; p < 3; ++p)
        if (free_dof(node, p) > 0.0)
          bound = std::max(bound, std::abs(diag[p][0]) + std::abs(diag[p][1]) +
                                      std::abs(diag[p][2]) + off[p]);
    }
  }
  if (parts)
    bound = parts->max(bound);
  out.omega_bound = std::sqrt(bound);
  out.dt_bound = 2.0 / out.omega_bound;

  // Lanczos from a start vector drawn per DOF of the body (a hash of its number), the same
  // whichever process holds the node.
  AlignedVector<double> q(3 * n), q_prev(3 * n, 0.0), w(3 * n, 0.0);
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
  for (std::int64_t node = 0; node < static_cast<std::int64_t>(n); ++node) {
    const std::uint64_t g = parts ? parts->global_node[node] : node;
    for (int d = 0; d < 3; ++d) {
      std::uint64_t z = (3 * g + static_cast<std::uint64_t>(d) + 1) * 0x9E3779B97F4A7C15ull;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      z ^= z >> 31;
      q[3 * node + d] = (static_cast<double>(z >> 11) * 0x1.0p-53 - 0.5) *
                        free_dof(static_cast<index_t>(node), d);
    }
  }
  const double q_norm = std::sqrt(dot(q, q));
  for (double& v : q)
    v /= q_norm;
  std::vector<double> alpha, beta{0.0};
  double theta = 0.0, theta_prev = 0.0;
  const int max_iter = 400;
  int stable_iters = 0;
  // w -= a q + b_prev q_prev on the owned rows, and w . w summed as dot() sums (row by row,
  // each row in order), in one pass.
  const auto update_and_norm = [&](double a, double b_prev) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      double s = 0.0;
      const std::size_t q0 = 3 * std::size_t{rows[r].first};
      for (std::size_t i = q0; i < q0 + 3 * std::size_t{rows[r].length}; ++i) {
        w[i] -= a * q[i] + b_prev * q_prev[i];
        s += w[i] * w[i];
      }
      row_sums[r] = s;
    }
    return sum_rows();
  };
  for (int it = 0; it < max_iter; ++it) {
    apply(q, w);
    const double a = dot(w, q);
    const double b_prev = beta.back();
    const double ww = update_and_norm(a, b_prev);
    alpha.push_back(a);
    theta = tridiagonal_max_eigenvalue(alpha, beta);
    out.iterations = it + 1;
    const double b = std::sqrt(ww);
    if (it > 0 && std::abs(theta - theta_prev) <= 1e-7 * theta) {
      if (++stable_iters >= 5)
        break;
    } else {
      stable_iters = 0;
    }
    theta_prev = theta;
    if (!(b > 1e-14 * theta))
      break; // invariant subspace found: theta is exact
    beta.push_back(b);
    std::swap(q_prev, q); // q = w / b, where q_prev was
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(w.size()); ++i)
      q[i] = w[i] / b;
  }
  out.omega_max = std::sqrt(theta);
  out.dt = 2.0 / out.omega_max;
  return out;
}

} // namespace ldem
