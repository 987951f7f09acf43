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
  std::array<std::uint64_t, kLimbs> limbs_{};
  double special_ = 0.0; // the sum of the terms that are not finite
};

// (Inline: the step adds a term per imposed node and per row, each a few nanoseconds.)
inline void ExactSum::add(double x) {
  // The IEEE fields: |x| = mant 2^(exponent - 1075) (normal) or mant 2^-1074 (subnormal).
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const auto exponent = static_cast<int>((bits >> 52) & 0x7ff);
  std::uint64_t mant = bits & ((std::uint64_t{1} << 52) - 1);
  if (exponent == 0x7ff) [[unlikely]] { // infinity or NaN
    special_ += x;
    return;
  }
  if (exponent != 0)
    mant |= std::uint64_t{1} << 52;
  if (mant == 0)
    return;
  // In units of 2^-160, |x| is mant shifted left by `shift` bits: t (a limb more, for the
  // high part of a shift that crosses into the top limb, which stays 0 in range).
  const int shift = (exponent == 0 ? -1074 : exponent - 1075) + kFractionBits;
  std::uint64_t t[kLimbs + 1] = {};
  if (shift < 0) {
    if (shift <= -64)
      return; // below 2^-160: dropped
    t[0] = mant >> -shift;
  } else {
    const int limb = shift / 64, bit = shift % 64;
    // mant has 53 bits: they must stay below the sign bit, 255.
    if (limb >= kLimbs || (limb + 1 == kLimbs && bit > 64 - 54)) [[unlikely]] {
      special_ += x > 0.0 ? HUGE_VAL : -HUGE_VAL; // beyond the range: shown as infinite
      return;
    }
    t[limb] = mant << bit;
    t[limb + 1] = bit != 0 ? mant >> (64 - bit) : 0;
  }
  // limbs + t, or for a negative x limbs + ~t + 1 (its two's complement): one carry chain.
  __extension__ using Wide = unsigned __int128; // (GCC's and Clang's; an add with its carry)
  const std::uint64_t negative = bits >> 63, flip = 0 - negative;
  Wide carry = static_cast<Wide>(limbs_[0]) + (t[0] ^ flip) + negative;
  limbs_[0] = static_cast<std::uint64_t>(carry);
  for (std::size_t i = 1; i < kLimbs; ++i) {
    carry = (carry >> 64) + limbs_[i] + (t[i] ^ flip);
    limbs_[i] = static_cast<std::uint64_t>(carry);
  }
}

} // namespace ldem
