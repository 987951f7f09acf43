// The body a case run steps: the case's Simulation in one process, or one subdomain per
// process of a distributed run (src/parallel/subdomain.hpp); no process holds the whole body.
//
// In a distributed run every member is collective: all processes call them in the same
// order. What the outputs need comes to the first process:
// - energies: each process's owned bar rows gathered and summed in the body's row order
//   (elastic and dissipated energy), its exact sums (work, damping, kinetic energy: Ledger,
//   ExactSum) added exactly: the bits of one process;
// - events of the bars each process owns, in the body's numbers and (step, bar) order;
// - probes: the owner's bar force, the reaction's per-node terms summed in the set's order;
// - the time step, the material's ranges and the end summary's counts from reductions;
// - fields.csv from the sampled bars each process owns.
// VTU snapshots (src/parallel/snapshot.hpp) and checkpoints (io/checkpoint.hpp) are written
// by every process into the one file, each value at its place.
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
  // A subdomain of the case per process (c.sim empty: the processes compute the body's time
  // step together in agree_on_body()). Not collective; throws InputError when this process's
  // subdomain cannot be built (its material, say).
  RunBody(BuiltCase& c, ProcessGrid grid, int rank);
  // The body's numbers agreed over the processes (after every process has built its
  // subdomain): its material summary, stable step and dt. Collective: throws the same
  // InputError on every process (K_r < 1, the time step) as one process would.
  void agree_on_body();

  bool distributed() const { return run_ != nullptr; }
  // The numbers of the body the resolved case reports: in a distributed run combined over the
  // processes (the same as one process's).
  BodyNumbers numbers() const;
  // fields.csv at `path`: the material of every bar (up to 2 million, else a regular sample),
  // for fields.png and the user's own statistics. Collective; the first process writes.
  void write_fields(const std::string& path);
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

  // The checkpoint file at `path` (io/checkpoint.hpp): `meta` (the first process's run
  // state), the body's progress, and the arrays each process owns written at their places, so
  // that the file is the same whatever the number of processes. Events not yet written stay
  // to be taken. Collective.
  void write_checkpoint(const std::string& path, const std::string& meta);
  // Loads the checkpoint at `path` (each process its window's nodes and bars) and returns its
  // meta. Throws InputError for a file that is not a checkpoint of this body (its size, dt) or
  // is corrupt. Collective.
  std::string read_checkpoint(const std::string& path);
  // The body's bars softening and broken now. Collective.
  std::array<std::uint64_t, 2> softening_and_broken();
  // The displacement of a node of the body, on the first process. Collective.
  Vec3 displacement(index_t node);
  // VTU snapshots: prepare_snapshots() makes the writer (what does not change during the run),
  // write_snapshot() writes the current state at `path` (the same bytes whatever the number of
  // processes; distributed, every process writes its part of the file). Collective.
  void prepare_snapshots();
  void write_snapshot(const std::string& path);

private:
  Simulation& sim(); // the case's, or this process's subdomain's
  // This process's nodes or bars in spans of the body's order: those it owns, or its window.
  std::vector<Span> node_spans(bool owned) const;
  std::vector<Span> bar_spans(bool owned) const;
  // Calls visit(place, values, count) for every piece of the checkpoint's arrays this process
  // owns: its values at places counted in doubles from the arrays' start (io/checkpoint.hpp).
  template <class F> void for_each_owned_piece(F&& visit);
  // This process's part of a report: probe terms, energy rows and sums, events (each list
  // preceded by its length), and the first process's reading of all parts.
  void append_probe_terms(std::vector<double>& out) const;
  void append_energy_rows(std::vector<double>& out);
  void append_events(std::vector<double>& out);
  void read_report(bool report);              // from received_
  void combine_numbers(const Lattice& whole); // numbers_ of the body from the processes' own
  std::vector<double> serial_probes() const;
  BuiltCase& c_;
  int rank_ = 0, ranks_ = 1;
  double dt_ = 0.0;
  StableStep stable_; // the body's
  BodyNumbers numbers_;
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
  std::vector<Event> events_; // gathered or kept by a checkpoint, not yet taken (first process)
  double initial_ = 0.0;      // the whole body's elastic + kinetic energy at t = 0
};

} // namespace ldem
