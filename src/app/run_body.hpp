// The body a case run steps: the case's Simulation in one process (run_body_serial.cpp), or
// one subdomain per process of a distributed run (run_body_distributed.cpp,
// src/parallel/subdomain.hpp); no process holds the whole body.
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
//
// What both bodies share is written once, here (run_body.cpp): the checkpoint file, from the
// pieces of the body's arrays each process owns; fields.csv from the rows the first process
// has; the counts of softening and broken bars; the probes that need no simulation.
#pragma once

#include "app/case_run.hpp"
#include "energy/ledger.hpp"
#include "io/checkpoint.hpp"
#include "parallel/subdomain.hpp"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace ldem {

class RunBody {
public:
  virtual ~RunBody() = default;
  RunBody(const RunBody&) = delete;
  RunBody& operator=(const RunBody&) = delete;

  // The body's numbers agreed over the processes (after every process has built its
  // subdomain): its material summary, stable step and dt. Collective: throws the same
  // InputError on every process (K_r < 1, the time step) as one process would.
  virtual void agree_on_body() = 0;

  virtual bool distributed() const = 0;
  // The numbers of the body the resolved case reports: in a distributed run combined over the
  // processes (the same as one process's).
  virtual BodyNumbers numbers() const = 0;
  // fields.csv at `path`: the material of every bar (up to 2 million, else a regular sample),
  // for fields.png and the user's own statistics. Collective; the first process writes.
  void write_fields(const std::string& path);
  virtual ProcessGrid grid() const = 0;
  // This process writes the outputs.
  bool writes() const { return rank_ == 0; }
  const Lattice& lattice() const { return *c_.lattice; }
  double dt() const { return dt_; }
  virtual const StableStep& stable_step() const = 0;
  std::uint64_t step_count() const { return sim().step_count(); }
  double time() const { return static_cast<double>(step_count()) * dt_; }

  // One step (and, distributed, the exchange of ghost nodes). With `report`, the probes at
  // the step's start and the energies; distributed, these and the step's events come to the
  // first process in one gather. A case with controlled velocities (BuiltCase::controls)
  // first sets their factors from their gauges at the step's start (control_factors;
  // distributed: the gauges' terms gathered and the factors sent back, the same on every
  // process whatever their number).
  virtual void step(bool report) = 0;
  // The whole body's energies of the last report step (first process).
  const EnergyReport& last_report() const { return report_; }
  // Whether the bar law has a fatigue life (its energies include fatigue_dissipated).
  bool counts_cycles() const { return sim().counts_cycles(); }
  // The threads this process steps with (Simulation::set_threads): the count set.
  int set_threads(int n) { return sim().set_threads(n); }
  int threads() const { return sim().threads(); }
  // The case's probes at the start of the last report step (first process).
  const std::vector<double>& last_probes() const { return probes_; }
  // The whole body's events gathered so far and not yet taken, in (step, bar) order (first
  // process; empty elsewhere). Not collective.
  virtual std::vector<Event> take_events() = 0;
  // The first node of the body with a displacement beyond `limit` or not finite, or
  // num_nodes(): the same on every process.
  virtual index_t first_node_beyond(double limit) = 0;
  // Every process's `value`, the largest (signals, decisions of the first process).
  virtual int max_over_processes(int value) const = 0;

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
  // Cycle jumping (a law with a fatigue life; docs/model.md, "Cycle jumping"). mark_lives()
  // starts a resolved window: each bar's life now is kept. jump_cycles() is the number of whole
  // cycles a jump may take once `window` cycles have been resolved since: each bar that still
  // counts used (life at the mark - life) / window per cycle, and the jump leaves at most
  // `breaks` of them at the end of their life, and is at most `cap` (0 when a bar would reach
  // its end within a cycle), and uses at most `fraction` of a whole life (1) in any bar.
  // Collective. jump_lives() moves every bar's life on by `cycles` at that rate, and marks
  // again.
  void mark_lives();
  double jump_cycles(std::uint64_t breaks, double window, double cap, double fraction);
  void jump_lives(double cycles, double window);
  // The displacement of a node of the body, on the first process. Collective.
  virtual Vec3 displacement(index_t node) = 0;
  // VTU snapshots: prepare_snapshots() makes the writer (what does not change during the run),
  // write_snapshot() writes the current state at `path` (the same bytes whatever the number of
  // processes; distributed, every process writes its part of the file). Collective.
  virtual void prepare_snapshots() = 0;
  virtual void write_snapshot(const std::string& path) = 0;

protected:
  RunBody(BuiltCase& c, int rank) : c_(c), rank_(rank) {}

  // The case's Simulation, or this process's subdomain's.
  virtual Simulation& sim() = 0;
  virtual const Simulation& sim() const = 0;
  // This process's nodes or bars in spans of the body's order: those it owns, or its window.
  virtual std::vector<Span> node_spans(bool owned) const = 0;
  virtual std::vector<Span> bar_spans(bool owned) const = 0;
  // For a checkpoint: the body's ledger (every process's exact sums added), with every event
  // not yet written added to events_, on the first process. Collective.
  virtual Ledger::State collect_ledger_and_events() = 0;
  // The rows (bar, E, Gf, e_p, e_r) of every stride-th bar of the body, in any order, on the
  // first process (empty elsewhere): each bar's material as a user reads it
  // (BarTable::properties). Collective.
  virtual std::vector<double> field_rows(index_t stride) = 0;

  // The events kept in events_, in (step, bar) order; none are kept after.
  std::vector<Event> take_kept_events();
  // A probe's value that needs no simulation: the total of a load at time t (times the factor
  // a script set on it, Simulation::set_load_factor).
  double load_probe(const ProbeSpec& p, double t) const;
  // The index of the platen named `name` in the case's platens (Conditions::platens).
  std::size_t platen_index(const std::string& name) const;
  // The factors of the controlled velocities for the step from t_n = step * dt, from their
  // gauges' values at t_n: f = clamp((rate t_{n+1} - g_n) / (response_time speed), -1, 1)
  // (docs/model.md, "Probe-controlled loading"). Into controls_.
  void control_factors(std::uint64_t step, const std::vector<double>& gauges);
  // The reaction probe's term of one node: its bar forces and load along the component (the
  // reaction is minus their sum over the set).
  static double reaction_term(const Simulation& sim, index_t node, int component);

  BuiltCase& c_;
  int rank_;
  double dt_ = 0.0;
  EnergyReport report_{};
  std::vector<double> probes_;
  std::vector<Event> events_; // gathered or kept by a checkpoint, not yet taken (first process)
  double initial_ = 0.0;      // the whole body's elastic + kinetic energy at t = 0
  std::vector<double> send_;  // gathers' and checkpoint pieces' buffer, kept from call to call
  std::vector<double> gauges_, controls_; // the controlled gauges and their factors (step)

private:
  // The body's progress as a checkpoint records it, without the ledger, report and events: its
  // step, dt, counts, bar law and state arrays.
  checkpoint::Progress body_progress() const;
  // Calls visit(place, values, count) for every piece of the state arrays of `p` this process
  // owns: its values at places counted in doubles from the arrays' start (io/checkpoint.hpp).
  template <class F> void for_each_owned_piece(const checkpoint::Progress& p, F&& visit);
};

// One process: steps c.sim.
std::unique_ptr<RunBody> make_serial_body(BuiltCase& c);
// A subdomain of the case per process (c.sim empty: the processes compute the body's time
// step together in agree_on_body()). Not collective; throws InputError when this process's
// subdomain cannot be built (its material, say).
std::unique_ptr<RunBody> make_distributed_body(BuiltCase& c, ProcessGrid grid, int rank);

} // namespace ldem
