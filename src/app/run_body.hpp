// The body a case run steps: the case's Simulation in one process, or one subdomain per
// process of a distributed run (src/parallel/subdomain.hpp) with a copy of the whole body on
// the first process that the outputs read.
//
// In a distributed run every member is collective: all processes call them in the same
// order. What the outputs need comes to the first process:
// - energies: each process's owned bar rows gathered and summed in the body's row order
//   (elastic and dissipated energy), its exact sums (work, damping, kinetic energy: Ledger,
//   ExactSum) added exactly: the bits of one process;
// - events of the bars each process owns, in the body's numbers and (step, bar) order;
// - probes: the owner's bar force, the reaction's per-node terms summed in the set's order;
// - checkpoints and the end summary: the owned nodes' displacements and owned bars'
//   histories copied into the whole-body Simulation (`whole`); VTU snapshots are written by
//   every process into the one file (src/parallel/snapshot.hpp).
#pragma once

#include "app/case_run.hpp"
#include "io/output.hpp"
#include "parallel/snapshot.hpp"
#include "parallel/subdomain.hpp"

#include <array>
#include <memory>
#include <vector>

namespace ldem {

class RunBody {
public:
  // One process: steps c.sim.
  explicit RunBody(BuiltCase& c);
  // A subdomain of the case per process. c.sim is the whole body on the first process (its
  // time step is every subdomain's) and empty elsewhere. Throws InputError when a subdomain
  // cannot be built.
  RunBody(BuiltCase& c, ProcessGrid grid, int rank);

  bool distributed() const { return run_ != nullptr; }
  ProcessGrid grid() const { return run_ ? run_->subdomain().grid : ProcessGrid{}; }
  // This process writes the outputs.
  bool writes() const { return rank_ == 0; }
  const Lattice& lattice() const { return *c_.lattice; }
  double dt() const { return dt_; }
  const StableStep& stable_step() const { return run_ ? stable_ : c_.sim->stable_step(); }
  std::uint64_t step_count() const;
  double time() const { return static_cast<double>(step_count()) * dt_; }

  // One step (and, distributed, the exchange of ghost nodes). With `report`, the probes at
  // the step's start and the energies; distributed, these and the step's events come to the
  // first process in one gather.
  void step(bool report);
  // The whole body's energies of the last report step (first process).
  const EnergyReport& last_report() const { return report_; }
  // The case's probes at the start of the last report step (first process).
  const std::vector<double>& last_probes() const { return probes_; }
  // The whole body's events gathered so far and not yet taken, in (step, bar) order (first
  // process; empty elsewhere). Not collective.
  std::vector<Event> take_events();
  // The first node of the body with a displacement beyond `limit` or not finite, or
  // num_nodes(): the same on every process.
  index_t first_node_beyond(double limit);
  // Every process's `value`, the largest (signals, decisions of the first process).
  int max_over_processes(int value) const;

  // The whole-body Simulation holding the current displacements u_n and u_{n-1} and the
  // histories (with `full` also the energy accumulators and the events not yet taken: what a
  // checkpoint saves). Called on every process; the first gets the Simulation, the others
  // nullptr.
  Simulation* whole(bool full);
  // VTU snapshots: prepare_snapshots() makes the writer (what does not change during the run),
  // write_snapshot() writes the current state at `path` (the same bytes whatever the number of
  // processes; distributed, every process writes its part of the file). Collective.
  void prepare_snapshots();
  void write_snapshot(const std::string& path);

  // After c.sim (first process) has loaded a checkpoint: every subdomain takes its window's
  // state from it.
  void spread_whole_state();

private:
  // This process's part of a report: probe terms, energy rows and sums, events (each list
  // preceded by its length), and the first process's reading of all parts.
  void append_probe_terms(std::vector<double>& out) const;
  void append_energy_rows(std::vector<double>& out);
  void append_events(std::vector<double>& out);
  void read_report(bool report); // from received_
  std::vector<double> serial_probes() const;
  BuiltCase& c_;
  int rank_ = 0, ranks_ = 1;
  double dt_ = 0.0;
  StableStep stable_; // the body's
  std::unique_ptr<SubdomainRun> run_;
  std::unique_ptr<LatticeVtuWriter> vtu_;             // one process
  std::unique_ptr<SubdomainVtuWriter> subdomain_vtu_; // distributed
  EnergyRows rows_; // this process's rows of a report, kept from call to call
  // The order of the body's bar rows among all processes' rows of a report, in rank order
  // (first process).
  std::vector<std::size_t> bar_order_;
  std::vector<double> halo_[4];
  std::vector<double> send_, received_; // gathers' buffers, kept from call to call
  EnergyReport report_{};
  std::vector<double> probes_;
  std::vector<Event> events_; // gathered, not yet taken (first process)
  double initial_ = 0.0;      // the whole body's elastic + kinetic energy at t = 0
};

} // namespace ldem
