// A sum of doubles that does not depend on the order of its terms: each term is converted
// exactly to a 256-bit fixed-point number (units of 2^-160, two's complement; bits of a term
// below 2^-160, about 7e-49, are dropped, the same way whatever the order) and the integers
// are added. The total is rounded to a double only when read. (A term that is not finite
// makes the sum its NaN or infinity; so does one of 2^95, some 4e28, or more, which does not
// fit: an energy in joules never comes near.) The energy ledger sums its work
// and damping with it, so that a run split over several processes, which add their parts
// first, gets the bits of one process.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

namespace ldem {

class ExactSum {
public:
  static constexpr int kLimbs = 4;
  static constexpr int kFractionBits = 160; // the value is limbs / 2^160

  inline void add(double x);
  void add(const ExactSum& other);
  // Twice the sum (exact, short of overflow beyond 2^94).
  void twice();
  // The sum rounded to a double (to nearest on its leading 64 bits).
  double value() const;
  bool operator==(const ExactSum&) const = default;

  // The state as doubles that carry it exactly (checkpoints, messages between processes):
  // the limbs as 32-bit halves, least significant first, then the sum of non-finite terms.
  static constexpr int kDoubles = 2 * kLimbs + 1;
  void write(double* out) const;
  void read(const double* in);

private:
  friend class ExactAccumulator;
  std::array<std::uint64_t, kLimbs> limbs_{};
  double special_ = 0.0; // the sum of the terms that are not finite
};

namespace exact_sum_detail {
// A double as an integer in units of 2^-160: |x| = mag 2^pos, mag < 2^53, 0 <= pos <= 202 (the
// top limb keeps its sign bit clear).
struct Term {
  bool negative;
  std::uint64_t mag;
  int pos;
};
// x's term, or false if there is none to add: a term that is not finite goes into `special`
// (the sum of such terms), one beyond the range too, as an infinity of its sign; one whose bits
// all lie below 2^-160 is dropped (and a term's bits below it, the same way whatever the sign
// and order).
inline bool term_of(double x, double& special, Term& term) {
  // The IEEE fields: |x| = mant 2^(exponent - 1075) (normal) or mant 2^-1074 (subnormal).
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const auto exponent = static_cast<int>((bits >> 52) & 0x7ff);
  std::uint64_t mant = bits & ((std::uint64_t{1} << 52) - 1);
  if (exponent == 0x7ff) [[unlikely]] { // infinity or NaN
    special += x;
    return false;
  }
  if (exponent != 0)
    mant |= std::uint64_t{1} << 52;
  const int shift = (exponent == 0 ? -1074 : exponent - 1075) + ExactSum::kFractionBits;
  if (shift < 0)
    mant = shift <= -64 ? 0 : mant >> -shift;
  if (mant == 0)
    return false;
  // mant has 53 bits: they must stay below the sign bit, 255.
  if (shift > 64 * ExactSum::kLimbs - 54) [[unlikely]] {
    special += x > 0.0 ? HUGE_VAL : -HUGE_VAL; // beyond the range: shown as infinite
    return false;
  }
  term = {(bits >> 63) != 0, mant, shift < 0 ? 0 : shift};
  return true;
}
} // namespace exact_sum_detail

// (Inline: the step adds a term per imposed node and per row, each a few nanoseconds.)
inline void ExactSum::add(double x) {
  exact_sum_detail::Term term;
  if (!exact_sum_detail::term_of(x, special_, term)) [[unlikely]]
    return;
  // |x| in limbs: t (a limb more, for the high part of a shift that crosses into the top
  // limb, which stays 0 in range).
  std::uint64_t t[kLimbs + 1] = {};
  const int limb = term.pos / 64, bit = term.pos % 64;
  t[limb] = term.mag << bit;
  t[limb + 1] = bit != 0 ? term.mag >> (64 - bit) : 0;
  // limbs + t, or for a negative x limbs + ~t + 1 (its two's complement): one carry chain.
  __extension__ using Wide = unsigned __int128; // (GCC's and Clang's; an add with its carry)
  const std::uint64_t negative = term.negative ? 1 : 0, flip = 0 - negative;
  Wide carry = static_cast<Wide>(limbs_[0]) + (t[0] ^ flip) + negative;
  limbs_[0] = static_cast<std::uint64_t>(carry);
  for (std::size_t i = 1; i < kLimbs; ++i) {
    carry = (carry >> 64) + limbs_[i] + (t[i] ^ flip);
    limbs_[i] = static_cast<std::uint64_t>(carry);
  }
}

// The same sum as ExactSum, for loops that add many terms in a row: each term's 53 bits go to
// three of nine 32-bit digits, each digit a signed 64-bit count, with no carry from one digit
// to the next until the sum is read (sum()). ExactSum's adds wait on each other through their
// carry chain; these wait only where two terms share a digit. sum() gives the ExactSum of the
// same terms to the bit (tests/test_exact_sum.cpp).
class ExactAccumulator {
public:
  inline void add(double x);
  ExactSum sum() const;

private:
  static constexpr int kDigits = 2 * ExactSum::kLimbs + 1; // 288 bits: a term reaches bit 255
  void carry(); // each digit back to [0, 2^32), the last one signed
  std::array<std::int64_t, kDigits> digits_{};
  std::uint32_t adds_ = 0; // since the last carry: a digit moves by < 2^32 per add
  double special_ = 0.0;   // as ExactSum's
};

inline void ExactAccumulator::add(double x) {
  exact_sum_detail::Term term;
  if (!exact_sum_detail::term_of(x, special_, term)) [[unlikely]]
    return;
  __extension__ using Wide = unsigned __int128;
  const int digit = term.pos / 32;
  const Wide w = static_cast<Wide>(term.mag) << (term.pos % 32); // at most 84 bits
  const std::int64_t sign = term.negative ? -1 : 1;
  digits_[static_cast<std::size_t>(digit)] += sign * static_cast<std::int64_t>(w & 0xffffffffu);
  digits_[static_cast<std::size_t>(digit) + 1] +=
      sign * static_cast<std::int64_t>((w >> 32) & 0xffffffffu);
  digits_[static_cast<std::size_t>(digit) + 2] += sign * static_cast<std::int64_t>(w >> 64);
  if (++adds_ == (1u << 30)) [[unlikely]] // (2^30 parts below 2^32 each fit a digit's 63 bits)
    carry();
}

} // namespace ldem
