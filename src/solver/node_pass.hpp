// The node pass (internal to the solver): each node row of a line gathers the forces of its
// bars (from the bar pass's plane buffers or, for fast links, computed at the node from the
// pristine spring) and is integrated: v_{n+1/2} and u_{n+1}, and the row's terms of the energy
// sums. Not law-dependent: the bar law enters through the forces the bar pass wrote and through
// the pristine springs' constants (StepLayout::link_const).
#pragma once

#include "solver/core.hpp"

namespace ldem {

// The node rows of `line`, with the bar forces of its plane (`s_plane`) and of the plane below
// (`s_below`). Damped, Loads, Report: the integration's variant (damping, nodal loads, a report
// step's sums).
template <bool Damped, bool Loads, bool Report>
void node_rows_range(SimulationCore& core, std::size_t line, const double* s_plane,
                     const double* s_below);

} // namespace ldem
