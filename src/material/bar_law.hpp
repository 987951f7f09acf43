// What a bar law is to the solver: a type that the step's kernels, the slow path of the bar
// pass and the evaluations outside the step (energies, snapshots, probes) are all instantiated
// with, so that each formula of a law is written once (docs/architecture.md, "Adding a bar
// law"). A law value holds the constants of one bar (the bilinear law's e_p and e_r); its
// member functions are the law, inline and without side effects; the per-bar state it reads
// and updates (the bilinear law's history) lives in named per-bar arrays of the simulation.
#pragma once

#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ldem {

// What a bar is, as events and snapshots report it (the VTU `state` codes 0, 1, 2).
enum class BarState : unsigned char { Intact, Softening, Broken };

// A bar's current length l, its extension dl = l - l0 and its strain e = dl / l0, from its
// current vector (dx, dy, dz) = d0 + u_b - u_a. The one formula of the code for them: the
// kernels, the slow path and every evaluation outside the step take it, so that a threshold
// is tested on the same number wherever the test is made. The strain is the extension times
// 1 / l0 (computed once per family, `inv_l0 = 1.0 / l0`): a multiplication, where the vector
// loops could least afford a division.
struct Stretch {
  double l, dl, e;
};
inline Stretch stretch(double dx, double dy, double dz, double l0, double inv_l0) noexcept {
  const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double dl = l - l0;
  return {l, dl, dl * inv_l0};
}

// One per-bar state array of a law: its name (the checkpoint's list of arrays, the VTU
// snapshots' cell data) and whether the snapshots carry it.
struct StateArray {
  std::string_view name;
  bool in_snapshots;
};

// The interface every law provides (checked where the kernels are instantiated):
// - kName: its name in a case file; kStateArrays: its per-bar state arrays, by name; State: a
//   bar's state as one value (read from and written to those arrays by read() and write(), at
//   bar i of rows of pointers, one per array);
// - initial(): a new bar's state; precracked(): a bar broken before the run;
// - pristine(s): whether the bar has its initial state, so that it is a linear spring of
//   stiffness k, F = k (l - l0), until its strain passes elastic_limit(): the intact fast path
//   takes such bars with its own arithmetic (s = k - k l0 / l), the state untouched;
// - force_over_length(k, g, s): s = F / l of a bar of stiffness k = E A / l0 (area factor
//   included) at stretch g in state s;
// - changes(e, s): whether the bar's state changes at strain e (the kernels flag the row, and
//   the slow path calls update(e, s, emit), which updates s and calls emit(BarState) for each
//   state the bar enters);
// - elastic_energy(s_over_l, g, s): the energy stored at stretch g, from the force over length
//   the law gave there; dissipated_energy(EA, l0, s): what the bar has dissipated, from its
//   state alone; damage(EA, l0, s): that over what the bar dissipates when broken, 0 to 1;
//   state(s): Intact, Softening or Broken.
template <class L>
concept BarLaw = requires(const L law, typename L::State s, Stretch g, double x,
                          const double* const* arrays, double* const* out, std::int64_t i) {
  { L::kName } -> std::convertible_to<std::string_view>;
  { L::kStateArrays.size() } -> std::convertible_to<std::size_t>;
  { L::read(arrays, i) } -> std::same_as<typename L::State>;
  L::write(out, i, s);
  { law.initial() } -> std::same_as<typename L::State>;
  { L::precracked() } -> std::same_as<typename L::State>;
  { law.pristine(s) } -> std::same_as<bool>;
  { law.elastic_limit() } -> std::same_as<double>;
  { law.force_over_length(x, g, s) } -> std::same_as<double>;
  { law.changes(x, s) } -> std::same_as<bool>;
  { law.elastic_energy(x, g, s) } -> std::same_as<double>;
  { law.dissipated_energy(x, x, s) } -> std::same_as<double>;
  { law.damage(x, x, s) } -> std::same_as<double>;
  { law.state(s) } -> std::same_as<BarState>;
};

} // namespace ldem
