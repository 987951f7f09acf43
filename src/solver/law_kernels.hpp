// The step and the evaluations of the bars instantiated for one bar law, as a run chooses them
// once (internal to the solver; a law's registry line is in laws.cpp). A Simulation holds the
// LawKernels of its law and calls through them; inside, every kernel is the law's own
// instantiation, with the law's functions inlined.
#pragma once

#include "material/bar_law.hpp"
#include "solver/bar_evaluation.hpp"
#include "solver/cycle_count.hpp"
#include "solver/walk.hpp"

#include <span>
#include <string_view>

namespace ldem {

struct LawKernels {
  std::string_view name;
  std::span<const StateArray> state_arrays;
  double (*row_elastic_limit)(const BarTable&, int family, index_t first_bar, index_t n);
  void (*init_states)(SimulationCore&, const std::vector<index_t>& precracked);
  void (*mark_damaged_rows)(SimulationCore&);
  // The step's walk over the body, in its variant for damping, loads and a report.
  void (*advance)(SimulationCore&, bool damped, bool loads, bool report);
  Simulation::BarEnergies (*report_bar_energies)(SimulationCore&);
  Simulation::BarEnergies (*bar_energies)(const SimulationCore&);
  void (*bar_snapshot)(const SimulationCore&, std::vector<std::uint8_t>&, std::vector<double>&,
                       std::vector<double>&, std::vector<double>*);
  void (*internal_forces)(const SimulationCore&, std::vector<double>&, std::vector<double>&,
                          std::vector<double>&);
  Vec3 (*node_force)(const SimulationCore&, index_t);
  double (*bar_force)(const SimulationCore&, index_t);
  BarState (*bar_state)(const SimulationCore&, index_t);
  // Laws with a fatigue life: the cycle count at the start of each step (cycle_count.hpp);
  // nullptr for the others.
  void (*count_cycles)(SimulationCore&);
};

template <class Law> void advance(SimulationCore& core, bool damped, bool loads, bool report) {
  if (damped) {
    if (loads)
      report ? advance_rows<Law, true, true, true>(core)
             : advance_rows<Law, true, true, false>(core);
    else
      report ? advance_rows<Law, true, false, true>(core)
             : advance_rows<Law, true, false, false>(core);
  } else {
    if (loads)
      report ? advance_rows<Law, false, true, true>(core)
             : advance_rows<Law, false, true, false>(core);
    else
      report ? advance_rows<Law, false, false, true>(core)
             : advance_rows<Law, false, false, false>(core);
  }
}

// The kernels of law `Law`, instantiated where this is called.
template <BarLaw Law> const LawKernels& law_kernels() {
  static const LawKernels kernels{Law::kName,
                                  Law::kStateArrays,
                                  &row_elastic_limit<Law>,
                                  &init_states<Law>,
                                  &mark_damaged_rows<Law>,
                                  &advance<Law>,
                                  &report_bar_energies<Law>,
                                  &bar_energies<Law>,
                                  &bar_snapshot<Law>,
                                  &internal_forces<Law>,
                                  &node_force<Law>,
                                  &bar_force<Law>,
                                  &bar_state<Law>,
                                  kCountsCycles<Law> ? &count_cycles<Law> : nullptr};
  return kernels;
}

} // namespace ldem
