// Eigen's dense products would otherwise split over the OpenMP threads; the modes are computed
// on one thread, so their digits do not depend on the thread count. Another file that uses
// Eigen in the same program must define it too (tests/test_modes.cpp does), or the program
// would hold two versions of Eigen's templates and the linker keep either.
#define EIGEN_DONT_PARALLELIZE
// GCC 12's AVX-512 headers trip this warning in Eigen's vectorised kernels (a known false alarm,
// as in simulation.cpp).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include "solver/modes.hpp"

#include "util/error.hpp"

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <Spectra/SymEigsShiftSolver.h>
#include <Spectra/SymEigsSolver.h>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fmt/format.h>
#include <limits>
#include <numbers>

namespace ldem {

namespace {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// Nodes [lo, hi) of `nodes` in nested-dissection order: the box is cut across its longest side
// by a slab of two node planes (a corner plane and the centre plane half a module above it); no
// bar reaches across the slab (a bar spans at most L along any axis), so the two sides do not
// couple and their factors fill in only within each side and the slab, which is numbered last.
// On a 3-D body this fills the factor far less than a general-purpose ordering (16^3 modules:
// 7 times faster); on a plate, about as well.
void dissect(const Lattice& lat, std::vector<index_t>& nodes, std::size_t lo, std::size_t hi,
             std::vector<index_t>& order) {
  const double L = lat.L();
  Vec3 mn = lat.position(nodes[lo]), mx = mn;
  for (std::size_t i = lo; i < hi; ++i) {
    const Vec3 p = lat.position(nodes[i]);
    mn = {std::min(mn.x, p.x), std::min(mn.y, p.y), std::min(mn.z, p.z)};
    mx = {std::max(mx.x, p.x), std::max(mx.y, p.y), std::max(mx.z, p.z)};
  }
  int axis = 0;
  for (int d = 1; d < 3; ++d)
    if (mx[d] - mn[d] > mx[axis] - mn[axis])
      axis = d;
  if (hi - lo < 64 || mx[axis] - mn[axis] < 2.5 * L) {
    order.insert(order.end(), nodes.begin() + static_cast<std::ptrdiff_t>(lo),
                 nodes.begin() + static_cast<std::ptrdiff_t>(hi));
    return;
  }
  // The slab [c, c + L) around the middle holds one corner plane and one centre plane.
  const double c = std::floor(0.5 * (mn[axis] + mx[axis]) / L) * L - 0.25 * L;
  const auto first = nodes.begin() + static_cast<std::ptrdiff_t>(lo);
  const auto last = nodes.begin() + static_cast<std::ptrdiff_t>(hi);
  const auto below_end =
      std::stable_partition(first, last, [&](index_t n) { return lat.position(n)[axis] < c; });
  const auto above_end = std::stable_partition(
      below_end, last, [&](index_t n) { return lat.position(n)[axis] >= c + L; });
  const auto mid1 = static_cast<std::size_t>(below_end - nodes.begin());
  const auto mid2 = static_cast<std::size_t>(above_end - nodes.begin());
  dissect(lat, nodes, lo, mid1, order);
  dissect(lat, nodes, mid1, mid2, order);
  order.insert(order.end(), above_end, last);
}

// Free DOF numbered node by node in nested-dissection order (x, y, z of a node together), held
// DOF -1; indexed by 3 node + axis.
std::vector<std::int64_t> number_free_dofs(const Simulation& sim, std::int64_t& count) {
  const Lattice& lat = sim.lattice();
  const index_t nn = lat.num_nodes();
  std::vector<index_t> nodes(nn), order;
  for (index_t n = 0; n < nn; ++n)
    nodes[n] = n;
  order.reserve(nn);
  dissect(lat, nodes, 0, nn, order);
  std::vector<std::int64_t> index(3 * static_cast<std::size_t>(nn), -1);
  count = 0;
  for (index_t n : order)
    for (int d = 0; d < 3; ++d)
      if (!(sim.held(n) & (1u << d)))
        index[3 * static_cast<std::size_t>(n) + d] = count++;
  return index;
}

// A = M^-1/2 K M^-1/2 on the free DOF. Every diagonal entry is stored (zero for a DOF without
// bars), so that a shift can be added in place.
SparseMatrix assemble(const Simulation& sim, const std::vector<std::int64_t>& dof,
                      std::int64_t n_free) {
  const Lattice& lat = sim.lattice();
  const BarTable& table = sim.table();
  std::vector<Eigen::Triplet<double, int>> t;
  t.reserve(static_cast<std::size_t>(n_free) + 36 * static_cast<std::size_t>(lat.num_bars()));
  for (std::int64_t i = 0; i < n_free; ++i)
    t.emplace_back(static_cast<int>(i), static_cast<int>(i), 0.0);
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    if (sim.bar_state(bar) == BarState::Broken)
      continue;
    const FamilyInfo& fi = lat.family(lat.bar_address(bar).family);
    // E A / l0 with the boundary area factor
    const double k = table.axial_stiffness(lat, bar) /
                     table.family(static_cast<int>(lat.bar_address(bar).family)).l0;
    const double e[3] = {fi.d0.x / fi.l0, fi.d0.y / fi.l0, fi.d0.z / fi.l0};
    const auto [a, b] = lat.bar_nodes(bar);
    const double rsm_a = 1.0 / std::sqrt(sim.mass(a)), rsm_b = 1.0 / std::sqrt(sim.mass(b));
    // Blocks k e e^T at (a, a) and (b, b), -k e e^T at (a, b) and (b, a), scaled by M^-1/2.
    const index_t nodes[2] = {a, b};
    const double rsm[2] = {rsm_a, rsm_b};
    for (int p = 0; p < 2; ++p)
      for (int q = 0; q < 2; ++q) {
        const double sign = p == q ? 1.0 : -1.0;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const std::int64_t row = dof[3 * static_cast<std::size_t>(nodes[p]) + r];
            const std::int64_t col = dof[3 * static_cast<std::size_t>(nodes[q]) + c];
            const double v = sign * k * e[r] * e[c] * rsm[p] * rsm[q];
            if (row >= 0 && col >= 0 && v != 0.0)
              t.emplace_back(static_cast<int>(row), static_cast<int>(col), v);
          }
      }
  }
  SparseMatrix A(n_free, n_free);
  A.setFromTriplets(t.begin(), t.end()); // duplicates summed
  return A;
}

// The shift-invert operation y = (A - sigma I)^-1 x for Spectra, by Eigen's supernodal sparse
// LU in the nested-dissection order of the DOF numbering. A - sigma I is symmetric positive
// definite for sigma < 0 (K is positive semi-definite), so the diagonal pivots need no
// exchange (pivot threshold 0) and the determinant is positive.
class ShiftedLu {
public:
  using Scalar = double;
  explicit ShiftedLu(const SparseMatrix& a) : a_(a) {}
  Eigen::Index rows() const { return a_.rows(); }
  Eigen::Index cols() const { return a_.cols(); }
  void set_shift(double sigma) {
    SparseMatrix shifted = a_;
    for (Eigen::Index i = 0; i < shifted.rows(); ++i)
      shifted.coeffRef(i, i) -= sigma;
    lu_.isSymmetric(true);
    lu_.setPivotThreshold(0.0);
    lu_.compute(shifted);
    if (lu_.info() != Eigen::Success || !(lu_.signDeterminant() > 0))
      throw InputError(fmt::format("modes: the shifted stiffness matrix (shift {:.3g} s^-2) is not "
                                   "positive definite; cannot factorise it",
                                   sigma));
  }
  void perform_op(const double* x, double* y) const {
    Eigen::Map<const Eigen::VectorXd> xv(x, a_.rows());
    Eigen::Map<Eigen::VectorXd> yv(y, a_.rows());
    yv = lu_.solve(xv);
  }

private:
  const SparseMatrix& a_;
  Eigen::SparseLU<SparseMatrix, Eigen::NaturalOrdering<int>> lu_;
};

// P (A - sigma I)^-1 P with P = I - Z Z^T, the projection out of the zero-energy modes Z found
// by a first run, for a second run that finds the elastic modes (the largest 1 / (lambda -
// sigma) that remain). Without it, those modes come out wrong by eps (diag / |sigma|) (lambda /
// |sigma|), 1e-3 on a free body of 4 x 3 x 2 modules: each solve leaves a round-off component
// of eps diag / |sigma| along the zero-energy modes, the next amplifies it by lambda / |sigma|
// against the elastic part, and the Lanczos recurrence, which keeps only the tridiagonal
// projection, loses what its reorthogonalisation removes; Spectra's residual estimates do not
// see it. Projecting after each solve removes the component before it grows.
class DeflatedLu {
public:
  using Scalar = double;
  DeflatedLu(const ShiftedLu& lu, const Eigen::MatrixXd& z) : lu_(lu), z_(z) {}
  Eigen::Index rows() const { return lu_.rows(); }
  Eigen::Index cols() const { return lu_.cols(); }
  void perform_op(const double* x, double* y) const {
    Eigen::Map<const Eigen::VectorXd> xv(x, rows());
    Eigen::Map<Eigen::VectorXd> yv(y, rows());
    const Eigen::VectorXd px = xv - z_ * (z_.transpose() * xv);
    lu_.perform_op(px.data(), y);
    yv -= z_ * (z_.transpose() * yv);
  }
  // A start vector in the range of P: pseudo-random (a fixed sequence, as Spectra's own), so
  // that no mode is missed for want of a component.
  Eigen::VectorXd start() const {
    Eigen::VectorXd v(rows());
    std::uint64_t state = 0x9E3779B97F4A7C15ull;
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      v[i] = static_cast<double>(state >> 11) * 0x1.0p-53 - 0.5;
    }
    v -= z_ * (z_.transpose() * v);
    return v;
  }

private:
  const ShiftedLu& lu_;
  const Eigen::MatrixXd& z_;
};

// Shift relative to the largest diagonal entry of A (of the order of omega_max^2): small enough
// to leave the lowest eigenvalues well separated in 1 / (lambda - sigma), large enough that the
// factorisation of a singular K stays far from round-off (condition number about 1e9).
constexpr double kShift = -1e-9;
// Eigenvalues below this (relative to the largest diagonal entry) are zero-energy modes: the
// factorisation's round-off moves the zero eigenvalues of a free body by 1e-17 to 1e-15 of that
// entry (measured on free boxes up to 20^3 modules), and a genuine elastic mode this low would
// need a body some 10^5 modules long.
constexpr double kZeroEnergy = 1e-12;
// A load whose components along the zero-energy modes exceed this fraction of its (mass-scaled)
// norm squared, i.e. an amplitude of 1e-6, has no static response. An equilibrated load's
// components are those of the Lanczos vectors' error, about 1e-10.
constexpr double kRigidLoad = 1e-12;

// F^T K^-1 F = g^T A^-1 g for g = M^-1/2 F orthogonal to the zero-energy modes Z: iterative
// refinement x += P (A - sigma I)^-1 (g - A x) with the shifted factorisation, P the projection
// out of Z (as in DeflatedLu). The error of each eigencomponent shrinks by |sigma| / (lambda -
// sigma) per step, at most 1e-3 unless the lowest elastic mode lies within 10^3 shifts of zero
// (a body some 10^4 modules long); the refinement stops at 1e-14 or when round-off stops it.
// NaN if it has not converged to 1e-9 in 100 steps.
double static_work(const ShiftedLu& op, const SparseMatrix& A, const Eigen::VectorXd& g,
                   const Eigen::MatrixXd& Z) {
  const Eigen::Index n = g.size();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n), r = g, dx(n);
  double work = 0.0, last = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 100; ++it) {
    op.perform_op(r.data(), dx.data());
    dx -= Z * (Z.transpose() * dx);
    x += dx;
    const double dw = std::abs(g.dot(dx));
    work = g.dot(x);
    if (dw <= 1e-14 * std::abs(work) || (it > 0 && dw >= last))
      return work;
    last = dw;
    r = g - A * x;
  }
  return last <= 1e-9 * std::abs(work) ? work : std::numeric_limits<double>::quiet_NaN();
}

} // namespace

std::size_t free_dof_count(const Simulation& sim) {
  std::int64_t n = 0;
  number_free_dofs(sim, n);
  return static_cast<std::size_t>(n);
}

std::vector<Mode> lowest_modes(const Simulation& sim, int count) {
  std::int64_t n_free = 0;
  const std::vector<std::int64_t> dof = number_free_dofs(sim, n_free);
  if (count < 1 || count >= n_free)
    throw InputError(fmt::format("modes: the number of modes must be at least 1 and below the "
                                 "number of free DOF ({}), got {}",
                                 n_free, count));
  const SparseMatrix A = assemble(sim, dof, n_free);
  double diag_max = 0.0;
  for (Eigen::Index i = 0; i < A.rows(); ++i)
    diag_max = std::max(diag_max, A.coeff(i, i));
  if (!(diag_max > 0.0))
    throw InputError("modes: no free DOF is connected by an unbroken bar");

  ShiftedLu op(A);
  const Eigen::Index nev = count;
  const double sigma = kShift * diag_max;
  const auto ncv_for = [&](Eigen::Index k) {
    return std::min<Eigen::Index>(n_free, std::max<Eigen::Index>(2 * k + 1, k + 20));
  };
  Spectra::SymEigsShiftSolver<ShiftedLu> eigs(op, nev, ncv_for(nev), sigma);
  eigs.init();
  const Eigen::Index nconv =
      eigs.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10, Spectra::SortRule::SmallestAlge);
  if (eigs.info() != Spectra::CompInfo::Successful || nconv < nev)
    throw InputError(fmt::format("modes: the Lanczos iteration found {} of the {} lowest modes "
                                 "({} iterations); ask for fewer",
                                 nconv, nev, eigs.num_iterations()));
  Eigen::VectorXd lambda = eigs.eigenvalues(); // ascending
  Eigen::MatrixXd psi = eigs.eigenvectors();
  Eigen::Index n_zero = 0;
  while (n_zero < nev && lambda[n_zero] <= kZeroEnergy * diag_max)
    ++n_zero;
  // Zero-energy modes and elastic ones: the elastic modes again, with the zero-energy ones
  // projected out (see DeflatedLu). With an elastic mode among those found, the zero-energy
  // modes, the lowest, are all found.
  if (n_zero > 0 && n_zero < nev) {
    const Eigen::MatrixXd Z = psi.leftCols(n_zero);
    DeflatedLu deflated(op, Z);
    const Eigen::Index k = nev - n_zero;
    Spectra::SymEigsSolver<DeflatedLu> elastic(deflated, k, ncv_for(k));
    elastic.init(deflated.start().data());
    const Eigen::Index kconv = elastic.compute(Spectra::SortRule::LargestAlge, 1000, 1e-10,
                                               Spectra::SortRule::LargestAlge);
    if (elastic.info() != Spectra::CompInfo::Successful || kconv < k)
      throw InputError(fmt::format("modes: the Lanczos iteration found {} of the {} lowest "
                                   "modes that store energy ({} iterations); ask for fewer",
                                   kconv, k, elastic.num_iterations()));
    const Eigen::VectorXd theta = elastic.eigenvalues(); // 1 / (lambda - sigma), descending
    lambda.tail(k) = theta.cwiseInverse().array() + sigma;
    psi.rightCols(k) = elastic.eigenvectors();
  }

  // Direction of each free DOF, for the participation shares.
  std::vector<int> axis(static_cast<std::size_t>(n_free));
  for (std::size_t i = 0; i < dof.size(); ++i)
    if (dof[i] >= 0)
      axis[static_cast<std::size_t>(dof[i])] = static_cast<int>(i % 3);

  std::vector<Mode> modes(static_cast<std::size_t>(nev));
  for (Eigen::Index m = 0; m < nev; ++m) {
    Mode& mode = modes[static_cast<std::size_t>(m)];
    mode.zero_energy = m < n_zero;
    mode.omega = mode.zero_energy ? 0.0 : std::sqrt(lambda[m]);
    mode.frequency_hz = mode.omega / (2.0 * std::numbers::pi);
    // phi = M^-1/2 psi, so 0.5 m phi^2 = 0.5 psi^2 DOF by DOF.
    double share[3] = {0.0, 0.0, 0.0};
    for (Eigen::Index i = 0; i < n_free; ++i)
      share[axis[static_cast<std::size_t>(i)]] += psi(i, m) * psi(i, m);
    const double total = share[0] + share[1] + share[2];
    for (int d = 0; d < 3; ++d)
      mode.participation[static_cast<std::size_t>(d)] = share[d] / total;
  }
  // Load shares: g = M^-1/2 F, so that phi^T F = psi^T g and F^T K^-1 F = g^T A^-1 g.
  Eigen::VectorXd g = Eigen::VectorXd::Zero(n_free);
  for (const NodalLoad& load : sim.conditions().loads)
    for (std::size_t q = 0; q < load.set.nodes.size(); ++q) {
      const index_t node = load.set.nodes[q];
      for (int d = 0; d < 3; ++d) {
        const std::int64_t i = dof[3 * static_cast<std::size_t>(node) + d];
        if (i >= 0)
          g[i] += load.weight_of(q) * load.force[d] / std::sqrt(sim.mass(node));
      }
    }
  // Defined if the zero-energy modes found are all there are (an elastic one is found too).
  const double g2 = g.squaredNorm();
  if (g2 > 0.0 && n_zero < nev) {
    const Eigen::MatrixXd Z = psi.leftCols(n_zero);
    const Eigen::VectorXd c0 = Z.transpose() * g;
    g -= Z * c0;
    const double work = c0.squaredNorm() <= kRigidLoad * g2
                            ? static_work(op, A, g, Z)
                            : std::numeric_limits<double>::quiet_NaN();
    if (work > 0.0)
      for (Eigen::Index m = 0; m < nev; ++m) {
        Mode& mode = modes[static_cast<std::size_t>(m)];
        const double c = psi.col(m).dot(g);
        mode.load_share = mode.zero_energy ? 0.0 : c * c / lambda[m] / work;
      }
  }
  return modes;
}

} // namespace ldem
