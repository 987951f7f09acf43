// The body of a run in one process: the case's Simulation, stepped as it is.
#include "app/run_body.hpp"
#include "io/output.hpp"

namespace ldem {

namespace {

class SerialBody final : public RunBody {
public:
  explicit SerialBody(BuiltCase& c) : RunBody(c, 0) {
    dt_ = c.sim->dt();
    report_ = c.sim->last_report();
  }

  void agree_on_body() override {} // one process: nothing to agree on
  bool distributed() const override { return false; }
  BodyNumbers numbers() const override { return body_numbers(*c_.sim); }
  ProcessGrid grid() const override { return {}; }
  const StableStep& stable_step() const override { return c_.sim->stable_step(); }
  void step(bool report) override;
  std::vector<Event> take_events() override;
  index_t first_node_beyond(double limit) override { return c_.sim->first_node_beyond(limit); }
  int max_over_processes(int value) const override { return value; } // the only process
  Vec3 displacement(index_t node) override { return c_.sim->displacement(node); }
  void prepare_snapshots() override {
    vtu_ = std::make_unique<LatticeVtuWriter>(*c_.sim, c_.spec.output.vtu_arrays,
                                              c_.spec.output.vtu_zlib);
  }
  void write_snapshot(const std::string& path) override;

private:
  Simulation& sim() override { return *c_.sim; }
  const Simulation& sim() const override { return *c_.sim; }
  // The whole body, in one span.
  std::vector<Span> node_spans(bool) const override { return {{0, 0, lattice().num_nodes()}}; }
  std::vector<Span> bar_spans(bool) const override { return {{0, 0, lattice().num_bars()}}; }
  Ledger::State collect_ledger_and_events() override;
  std::vector<double> field_rows(index_t stride) override;
  // The case's probes now, and a gauge's value now: its terms summed over each end's nodes in
  // order.
  std::vector<double> probes() const;
  double gauge(const BuiltCase::Gauge& g) const {
    double sums[2] = {0.0, 0.0};
    for (int e = 0; e < 2; ++e)
      for (index_t n : e == 0 ? g.from : g.to)
        sums[e] += probe_term(g, c_.sim->displacement(n));
    return gauge_value(g, sums[0], sums[1]);
  }
  // The simulation's events found since the last look, added to events_.
  void keep_new_events();

  std::unique_ptr<LatticeVtuWriter> vtu_;
};

void SerialBody::step(bool report) {
  if (!c_.controls.empty()) {
    // The controlled gauges now, as the probes sum them.
    gauges_.resize(c_.controls.size());
    for (std::size_t k = 0; k < c_.controls.size(); ++k)
      gauges_[k] = gauge(c_.probe_gauges[c_.controls[k].probe]);
    control_factors(c_.sim->step_count(), gauges_);
    c_.sim->set_control_factors(controls_);
  }
  if (report)
    probes_ = probes();
  c_.sim->step(report);
  if (report) {
    report_ = c_.sim->last_report();
    // A platen's force at t_n: the step's contact forces (from u_n and the friction's state).
    const auto& spec = c_.spec.probes;
    for (std::size_t i = 0; i < spec.size(); ++i)
      if (spec[i].kind == ProbeSpec::Kind::Platen) {
        probes_[i] = c_.sim->platen_force(platen_index(spec[i].platen))[spec[i].component];
      }
  }
}

std::vector<double> SerialBody::probes() const {
  const auto& probes = c_.spec.probes;
  const Simulation& sim = *c_.sim;
  std::vector<double> values(probes.size(), 0.0);
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ProbeSpec& p = probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce)
      values[i] = sim.bar_force(c_.probe_bars[i]);
    else if (p.kind == ProbeSpec::Kind::Reaction)
      // The support force that holds the set: minus the bar forces and loads on its nodes.
      for (index_t n : set_named(c_.sets, p.set).nodes)
        values[i] -= reaction_term(sim, n, p.component);
    else if (p.kind == ProbeSpec::Kind::Load)
      values[i] = load_probe(p, sim.time());
    else if (p.kind == ProbeSpec::Kind::Platen)
      continue; // set by the step (step())
    else if (p.kind == ProbeSpec::Kind::PlatenDisplacement)
      values[i] = sim.platen_offset(platen_index(p.platen))[p.component];
    else
      values[i] = gauge(c_.probe_gauges[i]);
  }
  return values;
}

void SerialBody::keep_new_events() {
  const std::vector<Event> more = c_.sim->take_events();
  events_.insert(events_.end(), more.begin(), more.end());
}

std::vector<Event> SerialBody::take_events() {
  // Those left from a checkpoint (or kept by one), then the newer ones.
  keep_new_events();
  return take_kept_events();
}

Ledger::State SerialBody::collect_ledger_and_events() {
  keep_new_events();
  return c_.sim->ledger_state();
}

std::vector<double> SerialBody::field_rows(index_t stride) {
  const Lattice& whole = lattice();
  std::vector<double> rows;
  for (index_t b = 0; b < whole.num_bars(); b += stride) {
    if (!whole.bar_present(b)) // a shaped body's box outside it
      continue;
    const BarTable::Properties p = c_.sim->table().properties(whole, b);
    rows.insert(rows.end(), {static_cast<double>(b), p.E, p.Gf, p.e_p, p.e_r});
  }
  return rows;
}

void SerialBody::write_snapshot(const std::string& path) {
  if (!vtu_)
    prepare_snapshots();
  vtu_->write(*c_.sim, path);
}

} // namespace

std::unique_ptr<RunBody> make_serial_body(BuiltCase& c) {
  return std::make_unique<SerialBody>(c);
}

} // namespace ldem
