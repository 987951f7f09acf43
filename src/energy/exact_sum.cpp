#include "energy/exact_sum.hpp"

#include <bit>
#include <cmath>

namespace ldem {

namespace {

using Limbs = std::array<std::uint64_t, ExactSum::kLimbs>;

void add_limbs(Limbs& a, const Limbs& b) {
  unsigned carry = 0;
  for (int i = 0; i < ExactSum::kLimbs; ++i) {
    const std::uint64_t s = a[i] + b[i];
    const unsigned c1 = s < a[i] ? 1u : 0u;
    a[i] = s + carry;
    carry = c1 | (a[i] < s ? 1u : 0u);
  }
}

void negate(Limbs& a) { // two's complement
  for (auto& l : a)
    l = ~l;
  const Limbs one{1, 0, 0, 0};
  add_limbs(a, one);
}

} // namespace

void ExactAccumulator::carry() {
  std::int64_t c = 0;
  for (int i = 0; i < kDigits; ++i) {
    const std::int64_t v = digits_[static_cast<std::size_t>(i)] + c;
    if (i + 1 == kDigits) {
      digits_[static_cast<std::size_t>(i)] = v;
    } else {
      digits_[static_cast<std::size_t>(i)] = v & 0xffffffff;
      c = v >> 32; // (arithmetic: floor(v / 2^32))
    }
  }
  adds_ = 0;
}

ExactSum ExactAccumulator::sum() const {
  // The digits carried: digits 0 to 7 hold the sum modulo 2^256 (ExactSum's two's complement),
  // digit 8 the rest (its sign, in range).
  ExactAccumulator a = *this;
  a.carry();
  ExactSum s;
  for (std::size_t j = 0; j < ExactSum::kLimbs; ++j)
    s.limbs_[j] = static_cast<std::uint64_t>(a.digits_[2 * j]) |
                  (static_cast<std::uint64_t>(a.digits_[2 * j + 1]) << 32);
  s.special_ = special_;
  return s;
}

void ExactSum::add(const ExactSum& other) {
  add_limbs(limbs_, other.limbs_);
  special_ += other.special_;
}

void ExactSum::twice() {
  for (int i = kLimbs - 1; i > 0; --i)
    limbs_[i] = (limbs_[i] << 1) | (limbs_[i - 1] >> 63);
  limbs_[0] <<= 1;
}

double ExactSum::value() const {
  if (special_ != 0.0 || std::isnan(special_))
    return special_;
  Limbs a = limbs_;
  const bool negative = (a[kLimbs - 1] >> 63) != 0;
  if (negative)
    negate(a);
  int top = kLimbs - 1;
  while (top >= 0 && a[static_cast<std::size_t>(top)] == 0)
    --top;
  if (top < 0)
    return 0.0;
  // The leading 64 bits, with any bit below them kept as a sticky last bit so that the
  // conversion to 53 bits rounds to nearest as the exact value would.
  const int lead = 63 - std::countl_zero(a[static_cast<std::size_t>(top)]); // bit in its limb
  const int p = 64 * top + lead; // highest set bit of the whole number
  std::uint64_t head = 0;
  bool sticky = false;
  if (p < 64) {
    head = a[0];
  } else {
    const int low = p - 63; // the bit that becomes bit 0 of head
    const int limb = low / 64, bit = low % 64;
    head = a[static_cast<std::size_t>(limb)] >> bit;
    if (bit != 0)
      head |= a[static_cast<std::size_t>(limb + 1)] << (64 - bit);
    sticky = bit != 0 && (a[static_cast<std::size_t>(limb)] << (64 - bit)) != 0;
    for (int i = 0; i < limb && !sticky; ++i)
      sticky = a[static_cast<std::size_t>(i)] != 0;
    if (sticky)
      head |= 1;
  }
  const int scale = (p < 64 ? 0 : p - 63) - kFractionBits;
  const double v = std::ldexp(static_cast<double>(head), scale);
  return negative ? -v : v;
}

void ExactSum::write(double* out) const {
  for (std::size_t i = 0; i < kLimbs; ++i) {
    out[2 * i] = static_cast<double>(limbs_[i] & 0xffffffffu);
    out[2 * i + 1] = static_cast<double>(limbs_[i] >> 32);
  }
  out[2 * kLimbs] = special_;
}

void ExactSum::read(const double* in) {
  for (std::size_t i = 0; i < kLimbs; ++i)
    limbs_[i] =
        static_cast<std::uint64_t>(in[2 * i]) | (static_cast<std::uint64_t>(in[2 * i + 1]) << 32);
  special_ = in[2 * kLimbs];
}

} // namespace ldem
