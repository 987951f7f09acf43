// ExactSum (src/energy/exact_sum.hpp): the sums of the energy ledger, whose bits must not
// depend on the order of the terms (nor on how a distributed run splits them).
#include "energy/exact_sum.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <limits>
#include <random>
#include <vector>

namespace ldem {
namespace {

// n terms of both signs, their magnitudes spread evenly over the decades [lo, hi).
std::vector<double> random_terms(std::size_t n, double lo, double hi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> mant(-1.0, 1.0), decade(lo, hi);
  std::vector<double> terms(n);
  for (double& x : terms)
    x = mant(rng) * std::pow(10.0, decade(rng));
  return terms;
}

ExactSum sum_of(const std::vector<double>& terms) {
  ExactSum s;
  for (double x : terms)
    s.add(x);
  return s;
}

// Terms of both signs over 40 decades, as a run's work and damping terms are (1e-30 J to
// 1e10 J): in order, reversed, shuffled, and in three parts added separately then together,
// the sum is the same number to the bit.
TEST(ExactSum, SameBitsInAnyOrderAndSplit) {
  std::mt19937_64 rng(7);
  const std::vector<double> terms = random_terms(20000, -30.0, 10.0, 7);
  const ExactSum forward = sum_of(terms);
  std::vector<double> other = terms;
  std::reverse(other.begin(), other.end());
  EXPECT_EQ(sum_of(other), forward);
  std::shuffle(other.begin(), other.end(), rng);
  EXPECT_EQ(sum_of(other), forward);
  ExactSum parts[3];
  for (std::size_t i = 0; i < terms.size(); ++i)
    parts[i % 3].add(terms[i]);
  ExactSum joined = parts[2];
  joined.add(parts[0]);
  joined.add(parts[1]);
  EXPECT_EQ(joined, forward);
  EXPECT_EQ(joined.value(), forward.value());
  // Ordinary summation does depend on the order (which is why the ledger does not use it).
  double a = 0.0, b = 0.0;
  for (double x : terms)
    a += x;
  for (double x : other)
    b += x;
  EXPECT_NE(a, b);
  // Every term and its negative: exactly zero.
  ExactSum zero = forward;
  for (double x : other)
    zero.add(-x);
  EXPECT_EQ(zero.value(), 0.0);
  EXPECT_EQ(zero, ExactSum{});
}

// Values whose exact sum is known: the sum is exact, then rounded once to nearest.
TEST(ExactSum, ExactThenRoundedOnce) {
  // 1e16 + 1 - 1e16 = 1 (in doubles, 1e16 + 1 rounds to 1e16 and the sum gives 0).
  EXPECT_EQ(sum_of({1e16, 1.0, -1e16}).value(), 1.0);
  // A term 2^-100 survives next to 1.
  EXPECT_EQ(sum_of({1.0, std::ldexp(1.0, -100), -1.0}).value(), std::ldexp(1.0, -100));
  // 1 + 2^-53 + 2^-80 lies above the midpoint between 1 and the next double 1 + 2^-52: it
  // rounds up (added in order, doubles give 1: 1 + 2^-53 is a tie that rounds to even).
  EXPECT_EQ(sum_of({1.0, std::ldexp(1.0, -53), std::ldexp(1.0, -80)}).value(),
            1.0 + std::ldexp(1.0, -52));
  // Exactly the midpoint rounds to even.
  EXPECT_EQ(sum_of({1.0, std::ldexp(1.0, -53)}).value(), 1.0);
  // Negative sums, large and small magnitudes.
  EXPECT_EQ(sum_of({-3.5}).value(), -3.5);
  EXPECT_EQ(sum_of({2.0, -7.25}).value(), -5.25);
  EXPECT_EQ(sum_of({1e20, 1e20}).value(), 2e20);
  // 1e-40 has bits below 2^-160, which are dropped: the sum is within 2^-160 of it.
  EXPECT_NEAR(sum_of({-1e-40}).value(), -1e-40, std::ldexp(1.0, -160));
  // Below the resolution 2^-160 (about 7e-49), a term is dropped.
  EXPECT_EQ(sum_of({1e-50}).value(), 0.0);
  // Twice: 2 (x + y).
  ExactSum s = sum_of({0.1, 0.7});
  s.twice();
  EXPECT_EQ(s.value(), 2.0 * sum_of({0.1, 0.7}).value());
}

// The state carried by doubles (checkpoints, messages between processes) is the same sum, and
// a term that is not finite makes the sum say so.
TEST(ExactSum, CarriedByDoublesAndNonFinite) {
  const ExactSum s = sum_of({3.0e-12, -1.0e5, 42.0, -7.0e-30});
  double buffer[ExactSum::kDoubles];
  s.write(buffer);
  ExactSum t;
  t.read(buffer);
  EXPECT_EQ(t, s);
  EXPECT_EQ(t.value(), s.value());
  EXPECT_TRUE(std::isinf(sum_of({1.0, HUGE_VAL}).value()));
  EXPECT_TRUE(std::isnan(sum_of({1.0, std::numeric_limits<double>::quiet_NaN()}).value()));
  EXPECT_TRUE(std::isinf(sum_of({1e30}).value())); // beyond 2^95: not representable
}

// ExactAccumulator: the ExactSum of the same terms to the bit, whatever their signs and
// magnitudes (the digits only defer the carries), through its carries of 2^30 terms, and with
// terms that are not finite, out of range or below 2^-160.
ExactSum accumulated(const std::vector<double>& terms) {
  ExactAccumulator a;
  for (double x : terms)
    a.add(x);
  return a.sum();
}

TEST(ExactAccumulator, TheSameBitsAsExactSum) {
  std::vector<double> terms = random_terms(50000, -45.0, 25.0, 11);
  // Subnormals, terms that lose bits below 2^-160 or all of them, and the largest in range
  // (mantissa all ones just below 2^95).
  for (const double x : {std::numeric_limits<double>::denorm_min(), -1e-310, 1e-47, -3e-49, 1e-50,
                         std::ldexp(1.0, -160), -std::ldexp(1.0, -161),
                         std::ldexp(std::ldexp(1.0, 53) - 1.0, 94 - 52), 0.0, -0.0})
    terms.push_back(x);
  const ExactSum direct = sum_of(terms);
  EXPECT_EQ(accumulated(terms), direct);
  EXPECT_EQ(accumulated(terms).value(), direct.value());
  // Each term and its negative: exactly zero, as ExactSum's own.
  std::vector<double> both = terms;
  for (double x : terms)
    both.push_back(-x);
  EXPECT_EQ(accumulated(both), ExactSum{});
  // Terms that are not finite or beyond the range: the same special value.
  for (const double bad :
       {HUGE_VAL, -HUGE_VAL, std::numeric_limits<double>::quiet_NaN(), 1e30, -1e30}) {
    std::vector<double> t = {1.0, bad, -2.5};
    const ExactSum a = accumulated(t), b = sum_of(t);
    EXPECT_EQ(std::isnan(a.value()), std::isnan(b.value())) << bad;
    if (!std::isnan(b.value())) {
      EXPECT_EQ(a.value(), b.value()) << bad;
    }
  }
}

TEST(ExactAccumulator, CarriesPastTwoToTheThirtyTerms) {
  // 2^30 + 3 terms of x = (2^53 - 1) 2^-41: in units of 2^-160 its 53 bits start at bit 119,
  // bit 23 of a digit, so its first two digit parts are 2^32 - 2^23 and 2^32 - 1 and a digit
  // reaches 2^62 by the 2^30th term: the digits carry once on the way. The sum n x exactly,
  // from ExactSum by doubling and adding.
  const double x = std::ldexp(std::ldexp(1.0, 53) - 1.0, -41);
  const std::uint64_t n = (std::uint64_t{1} << 30) + 3;
  ExactAccumulator a;
  for (std::uint64_t i = 0; i < n; ++i)
    a.add(x);
  ExactSum expected, power;
  power.add(x);
  for (std::uint64_t m = n; m != 0; m >>= 1) {
    if (m & 1)
      expected.add(power);
    power.twice();
  }
  EXPECT_EQ(a.sum(), expected);
  EXPECT_EQ(a.sum().value(), static_cast<double>(n) * x); // (n x has 84 bits: rounded once)
}

} // namespace
} // namespace ldem
