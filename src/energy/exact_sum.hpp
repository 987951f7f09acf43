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
#include <cstdint>

namespace ldem {

class ExactSum {
public:
  static constexpr int kLimbs = 4;
  static constexpr int kFractionBits = 160; // the value is limbs / 2^160

  void add(double x);
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

} // namespace ldem
