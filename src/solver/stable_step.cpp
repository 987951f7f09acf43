#include "solver/stable_step.hpp"

#include "energy/exact_sum.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace ldem {

namespace {

// Undamaged axial stiffness EA / l0 of every bar (including the boundary area factor).
std::vector<double> bar_stiffness(const Lattice& lat, const BarTable& table) {
  if (table.per_bar())
    return table.k_bar();
  std::vector<double> k(lat.num_bars());
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    const double kf = table.family(f).k;
    for (index_t kk = 0; kk < fi.nk; ++kk)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i)
          k[lat.bar(static_cast<Family>(f), i, j, kk)] =
              kf * lat.area_factor(static_cast<Family>(f), i, j, kk);
  }
  return k;
}

// Calls f(other node, unit vector towards it, bar stiffness) for every bar of node i of a row.
template <class F>
void for_each_bar_of(index_t i, const RowLink* links, int nl, const std::vector<double>& kb,
                     F&& f) {
  for (int l = 0; l < nl; ++l) {
    const RowLink& L = links[l];
    if (i < L.ilo || i >= L.ihi)
      continue;
    const double len = std::sqrt(L.r0.x * L.r0.x + L.r0.y * L.r0.y + L.r0.z * L.r0.z);
    const double e[3] = {L.r0.x / len, L.r0.y / len, L.r0.z / len};
    f(static_cast<index_t>(L.other_base + i), e, kb[static_cast<std::size_t>(L.bar_base + i)]);
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
  const std::vector<double> kb = bar_stiffness(lat, table);
  const std::size_t n = lat.num_nodes();
  // The rows of nodes this process owns (a row along x is never split between processes).
  std::vector<NodeRow> rows = node_rows(lat);
  if (parts)
    rows.erase(std::remove_if(rows.begin(), rows.end(),
                              [&](const NodeRow& r) { return !parts->owned[r.first]; }),
               rows.end());
  const std::int64_t nrows = static_cast<std::int64_t>(rows.size());
  // 1 / sqrt(m) and the held DOF of every node; a ghost node's from its owner.
  std::vector<double> rsm(n);
  std::vector<unsigned char> held(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
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
  auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
    for_owned([&](const NodeRow& row) {
      for (index_t i = 0; i < row.length; ++i) {
        const index_t node = row.first + i;
        for (int d = 0; d < 3; ++d)
          scaled[3 * node + d] = x[3 * node + d] * rsm[node] * free_dof(node, d);
      }
    });
    if (parts)
      parts->exchange(scaled);
    for_owned([&](const NodeRow& row) {
      RowLink links[kMaxRowLinks];
      const int nl = row_links(lat, row, links);
      for (index_t i = 0; i < row.length; ++i) {
        const index_t node = row.first + i;
        double acc[3] = {0, 0, 0};
        for_each_bar_of(i, links, nl, kb, [&](index_t other, const double* e, double k) {
          double proj = 0.0;
          for (int d = 0; d < 3; ++d)
            proj += e[d] * (scaled[3 * node + d] - scaled[3 * other + d]);
          for (int d = 0; d < 3; ++d)
            acc[d] += k * proj * e[d];
        });
        for (int d = 0; d < 3; ++d)
          y[3 * node + d] = acc[d] * rsm[node] * free_dof(node, d);
      }
    });
  };
  // a . b over the owned nodes: each row's products added in order along it, the rows' sums
  // exactly (and with the other processes' rows), whatever their order.
  std::vector<double> row_sums(rows.size());
  auto dot = [&](const std::vector<double>& a, const std::vector<double>& b) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      double s = 0.0;
      const std::size_t q0 = 3 * std::size_t{rows[r].first};
      for (std::size_t q = q0; q < q0 + 3 * std::size_t{rows[r].length}; ++q)
        s += a[q] * b[q];
      row_sums[r] = s;
    }
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

  StableStep out;
  // Gershgorin: every eigenvalue lies below the largest absolute row sum.
  double bound = 0.0;
  for (const NodeRow& row : rows) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat, row, links);
    for (index_t i = 0; i < row.length; ++i) {
      const index_t node = row.first + i;
      double diag[3][3] = {}, off[3] = {};
      for_each_bar_of(i, links, nl, kb, [&](index_t other, const double* e, double k) {
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
  std::vector<double> q(3 * n), q_prev(3 * n, 0.0), w(3 * n, 0.0);
  for (std::size_t node = 0; node < n; ++node) {
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
  for (int it = 0; it < max_iter; ++it) {
    apply(q, w);
    const double a = dot(w, q);
    const double b_prev = beta.back();
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(w.size()); ++i)
      w[i] -= a * q[i] + b_prev * q_prev[i];
    alpha.push_back(a);
    theta = tridiagonal_max_eigenvalue(alpha, beta);
    out.iterations = it + 1;
    const double b = std::sqrt(dot(w, w));
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
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(w.size()); ++i) {
      q_prev[i] = q[i];
      q[i] = w[i] / b;
    }
  }
  out.omega_max = std::sqrt(theta);
  out.dt = 2.0 / out.omega_max;
  return out;
}

} // namespace ldem
