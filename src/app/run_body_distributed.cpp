// The body of a distributed run: a subdomain of the case per process (SubdomainRun), whose
// outputs come to the first process as one process would write them (run_body.hpp).
#include "app/run_body.hpp"
#include "material/field.hpp"
#include "parallel/comm.hpp"
#include "parallel/snapshot.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <optional>

namespace ldem {

namespace {

class DistributedBody final : public RunBody {
public:
  DistributedBody(BuiltCase& c, ProcessGrid grid, int rank);

  void agree_on_body() override;
  bool distributed() const override { return true; }
  BodyNumbers numbers() const override { return numbers_; }
  ProcessGrid grid() const override { return run_->subdomain().grid; }
  const StableStep& stable_step() const override { return stable_; }
  void step(bool report) override;
  std::vector<Event> take_events() override { return take_kept_events(); }
  index_t first_node_beyond(double limit) override;
  int max_over_processes(int value) const override;
  Vec3 displacement(index_t node) override;
  void prepare_snapshots() override;
  void write_snapshot(const std::string& path) override;

private:
  Simulation& sim() override { return run_->sim(); }
  const Simulation& sim() const override { return run_->sim(); }
  std::vector<Span> node_spans(bool owned) const override;
  std::vector<Span> bar_spans(bool owned) const override;
  Ledger::State collect_ledger_and_events() override;
  std::vector<double> field_rows(index_t stride) override;
  // This process's part of a report: probe terms, energy rows and sums, events (each list
  // preceded by its length), and the first process's reading of all parts.
  void append_probe_terms(std::vector<double>& out) const;
  // The controlled velocities' factors for this step, from their gauges (RunBody::step).
  void control();
  void append_energy_rows(std::vector<double>& out);
  void append_events(std::vector<double>& out);
  void read_report(bool report);              // from received_
  // A gauge from every process's terms of it (terms[rank], moved past them): each end's terms
  // in its nodes' order, as one process sums them.
  double gauge_from(const BuiltCase::Gauge& g, std::vector<const double*>& terms) const;
  void combine_numbers(const Lattice& whole); // numbers_ of the body from the processes' own

  int ranks_;
  StableStep stable_; // the body's
  BodyNumbers numbers_;
  std::unique_ptr<SubdomainRun> run_;
  std::unique_ptr<SubdomainVtuWriter> vtu_;
  EnergyRows rows_; // this process's rows of a report, kept from call to call
  // The order of the body's bar rows among all processes' rows of a report, in rank order
  // (first process).
  std::vector<std::size_t> bar_order_;
  std::vector<double> halo_[4];
  std::vector<double> received_; // gathers' buffer, kept from call to call
  std::vector<const double*> terms_; // each process's part of received_ (control)
};

int node_owner(const Subdomain& any, const Lattice& whole, index_t node) {
  const NodeAddress a = whole.node_address(node);
  return owner_rank(any, a.j, a.k);
}

int bar_owner(const Subdomain& any, const Lattice& whole, index_t bar) {
  const BarAddress a = whole.bar_address(bar);
  return owner_rank(any, a.j, a.k);
}

double DistributedBody::gauge_from(const BuiltCase::Gauge& g,
                                   std::vector<const double*>& terms) const {
  const Subdomain& sub = run_->subdomain();
  double sums[2] = {0.0, 0.0};
  for (int e = 0; e < 2; ++e)
    for (index_t n : e == 0 ? g.from : g.to)
      sums[e] += *terms[static_cast<std::size_t>(node_owner(sub, lattice(), n))]++;
  return gauge_value(g, sums[0], sums[1]);
}

// Appends a list's length, then reserves it: returns the length's place, to be set.
std::size_t open_list(std::vector<double>& out) {
  out.push_back(0.0);
  return out.size() - 1;
}
void close_list(std::vector<double>& out, std::size_t at) {
  out[at] = static_cast<double>(out.size() - at - 1);
}

DistributedBody::DistributedBody(BuiltCase& c, ProcessGrid grid, int rank)
    : RunBody(c, rank), ranks_(grid.py * grid.pz) {
  const Lattice& whole = *c.lattice;
  const Subdomain sub = make_subdomain(whole, grid, rank);
  Lattice local = window_lattice(sub, whole);
  // The window's material: the body's fields evaluated at the window's bars and modules
  // (random draws by the body's numbers, correlated fields from the body's one grid), the
  // values the whole body has there.
  const CaseSpec::Fields& given = c.spec.fields;
  std::vector<index_t> global_bars, modules;
  if (given.E || given.Gf || given.e_p || given.e_r || given.R_f || !c.spec.regions.empty()) {
    global_bars.resize(local.num_bars());
    for (index_t b = 0; b < local.num_bars(); ++b)
      global_bars[b] = global_bar(sub, local, whole, b);
  }
  // The window's modules (i, j, k), numbered i + nx (j + ny k) in the body.
  modules.reserve(local.num_modules());
  for (index_t k = sub.z.w0; k < sub.z.w1; ++k)
    for (index_t j = sub.y.w0; j < sub.y.w1; ++j)
      for (index_t i = 0; i < whole.nx(); ++i)
        modules.push_back(i + whole.nx() * (j + whole.ny() * k));
  const BarFields fields = case_fields(c.spec, whole, &global_bars, &modules);
  // The window's table names the body's bars and sums up the bars this process owns; the
  // processes' summaries combine into the body's below.
  BodyWindow window;
  window.body_bar = [&](index_t b) { return global_bar(sub, local, whole, b); };
  window.counted = [&](index_t b) {
    const BarAddress a = local.bar_address(b);
    return sub.owns(a.j + sub.y.w0, a.k + sub.z.w0, true);
  };
  std::optional<BarTable> table_built;
  try {
    table_built.emplace(local, c.spec.material, fields, &window);
  } catch (const InputError& e) {
    throw InputError(located(c.spec, c.path, e.what()));
  }
  BarTable& table = *table_built;
  numbers_.ranges = table.ranges();
  numbers_.ductility = table.ductility_summary();
  numbers_.per_bar = table.per_bar();
  if (rank == 0)
    c.warnings.insert(c.warnings.end(), table.warnings().begin(),
                      table.warnings().end()); // those of the case's values (the same on every
                                               // process)
  Conditions conditions = subdomain_conditions(sub, whole, local, c.conditions);
  // The body's bars of a list that lie in this window (owned or ghost), in its numbering.
  auto in_window = [&](const std::vector<index_t>& body_bars) {
    std::vector<index_t> bars;
    for (index_t b : body_bars) {
      const BarAddress a = whole.bar_address(b);
      const FamilyInfo& fl = local.family(a.family);
      if (a.j >= sub.y.w0 && a.j - sub.y.w0 < fl.nj && a.k >= sub.z.w0 && a.k - sub.z.w0 < fl.nk)
        bars.push_back(local.bar(a.family, a.i, a.j - sub.y.w0, a.k - sub.z.w0));
    }
    std::sort(bars.begin(), bars.end());
    return bars;
  };
  std::vector<index_t> precracked = in_window(c.precracked);
  const std::vector<index_t> lifeless = in_window(c.lifeless); // without a fatigue life
  SolverOptions options = c.options;
  options.defer_time_step = true; // the body's step, below
  run_ = std::make_unique<SubdomainRun>(sub, std::move(local), std::move(table),
                                        std::move(conditions), options, std::move(precracked));
  remove_fatigue_life(run_->sim(), lifeless);
}

void DistributedBody::agree_on_body() {
  const Lattice& whole = lattice();
  const BuiltCase& c = c_;
  const Subdomain& sub = run_->subdomain();
  // The body's material summary, stable step and dt, as one process finds them.
  try {
    combine_numbers(whole);
    run_->sim().set_platen_stiffness(numbers_.ranges.E[1], numbers_.ranges.rho[0]);
    stable_ = with_platens(distributed_stable_step(*run_, whole), run_->sim().conditions());
    dt_ = time_step_by_rule(c.options.step, stable_, numbers_.ranges.E[1], numbers_.ranges.rho[0],
                            whole.L(), c.options.damping);
  } catch (const InputError& e) {
    throw InputError(located(c.spec, c.path, e.what()));
  }
  run_->sim().set_time_step(stable_, dt_);
  check_end_time(c, dt_);
  numbers_.stable = stable_;
  numbers_.dt = dt_;
  // The memory of the busiest process per module it owns.
  numbers_.bytes_per_module = ldem::max_over_processes(
      run_->sim().bytes_per_module() * static_cast<double>(run_->sim().lattice().num_modules()) /
      (static_cast<double>(sub.y.m1 - sub.y.m0) * static_cast<double>(sub.z.m1 - sub.z.m0) *
       static_cast<double>(whole.nx())));
  // The place of every process's energy rows in the body's order, found once: the rows of a
  // report come in rank order, each process's in its own order.
  EnergyRows rows;
  run_->append_owned_row_keys(rows);
  bar_order_ = key_order(gather_on_first(rows.bar_keys));
}

void DistributedBody::combine_numbers(const Lattice& whole) {
  // The body's ranges and ductility from every process's owned bars: smallest of the
  // smallest, largest of the largest, counts added; the worst bar the body's first with the
  // smallest K_r.
  MaterialRanges& r = numbers_.ranges;
  for (double* range : {r.E, r.Gf, r.e_p, r.e_r_normal, r.rho}) {
    range[0] = min_over_processes(range[0]);
    range[1] = ldem::max_over_processes(range[1]);
  }
  DuctilitySummary& d = numbers_.ductility;
  for (double* lo : {&d.kr_min_normal, &d.kr_min_diag, &d.L_cr_min})
    *lo = min_over_processes(*lo);
  for (double* hi : {&d.kr_max_normal, &d.kr_max_diag})
    *hi = ldem::max_over_processes(*hi);
  d.bars_below_one =
      static_cast<std::uint64_t>(sum_over_processes(static_cast<double>(d.bars_below_one)));
  const double worst = min_over_processes(d.worst_kr);
  d.worst_bar = static_cast<index_t>(
      min_over_processes(d.worst_kr == worst ? static_cast<double>(d.worst_bar) : INFINITY));
  d.worst_kr = worst;
  // K_r < 1: refused, or allowed with a warning, as one process judges the body.
  if (auto warning = check_ductility(d, c_.spec.material, whole.num_bars(),
                                     whole.bar_centre(d.worst_bar), whole.L()))
    if (writes())
      c_.warnings.push_back(*warning);
}

std::vector<double> DistributedBody::field_rows(index_t stride) {
  // The sampled bars this process owns, gathered in rank order.
  const Lattice& whole = lattice();
  const Lattice& local = run_->sim().lattice();
  std::vector<double> rows;
  for (index_t b = 0; b < local.num_bars(); ++b) {
    const index_t g = global_bar(run_->subdomain(), local, whole, b);
    if (g % stride != 0 || !run_->owns_bar(b) || !whole.bar_present(g))
      continue;
    const BarTable::Properties p = run_->sim().table().properties(local, b);
    rows.insert(rows.end(), {static_cast<double>(g), p.E, p.Gf, p.e_p, p.e_r});
  }
  return gather_on_first(rows);
}

void DistributedBody::step(bool report) {
  const bool first_step = run_->sim().step_count() == 0; // energies are computed at step 0
  if (!c_.controls.empty())
    control();
  send_.clear();
  if (report)
    append_probe_terms(send_);
  run_->sim().step(report);
  exchange_halos(*run_, halo_);
  if (!report && !first_step)
    return;
  if (report) // the platens' forces at t_n, which the step found
    for (const ProbeSpec& p : c_.spec.probes)
      if (p.kind == ProbeSpec::Kind::Platen) {
        const ExactSum& f = run_->sim().platen_force_sum(
            platen_index(p.platen))[static_cast<std::size_t>(p.component)];
        send_.resize(send_.size() + ExactSum::kDoubles);
        f.write(send_.data() + send_.size() - ExactSum::kDoubles);
      }
  append_energy_rows(send_);
  append_events(send_);
  gather_on_first(send_, received_);
  read_report(report);
}

void DistributedBody::control() {
  // Each process's terms of the controlled gauges' nodes it owns, in the gauges' order; the
  // first process sums each end's terms in its nodes' order (as one process does), finds the
  // factors and sends them to all.
  const Lattice& whole = lattice();
  const Subdomain& sub = run_->subdomain();
  const Simulation& sim = run_->sim();
  send_.clear();
  for (const BuiltCase::Control& ctl : c_.controls) {
    const BuiltCase::Gauge& g = c_.probe_gauges[ctl.probe];
    for (const auto* nodes : {&g.from, &g.to})
      for (index_t n : *nodes)
        if (node_owner(sub, whole, n) == sub.rank)
          send_.push_back(
              probe_term(g, sim.displacement(run_->local_node(whole.node_address(n)))));
  }
  const std::size_t mine = send_.size();
  send_.insert(send_.begin(), static_cast<double>(mine));
  gather_on_first(send_, received_);
  controls_.resize(c_.controls.size());
  if (writes()) {
    terms_.clear();
    for (std::size_t pos = 0; pos < received_.size();
         pos += 1 + static_cast<std::size_t>(received_[pos]))
      terms_.push_back(received_.data() + pos + 1);
    gauges_.resize(c_.controls.size());
    for (std::size_t k = 0; k < c_.controls.size(); ++k)
      gauges_[k] = gauge_from(c_.probe_gauges[c_.controls[k].probe], terms_);
    control_factors(sim.step_count(), gauges_);
  }
  broadcast_from_first(controls_.data(), static_cast<int>(controls_.size()));
  run_->sim().set_control_factors(controls_);
}

void DistributedBody::append_probe_terms(std::vector<double>& out) const {
  // Each process evaluates what it owns: the probed bar, the set's nodes (in the set's order).
  const Lattice& whole = lattice();
  const Subdomain& sub = run_->subdomain();
  const Simulation& sim = run_->sim();
  const std::size_t at = open_list(out);
  for (std::size_t i = 0; i < c_.spec.probes.size(); ++i) {
    const ProbeSpec& p = c_.spec.probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce &&
        bar_owner(sub, whole, c_.probe_bars[i]) == sub.rank) {
      const BarAddress a = whole.bar_address(c_.probe_bars[i]);
      out.push_back(
          sim.bar_force(sim.lattice().bar(a.family, a.i, a.j - sub.y.w0, a.k - sub.z.w0)));
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      for (index_t n : set_named(c_.sets, p.set).nodes)
        if (node_owner(sub, whole, n) == sub.rank)
          out.push_back(reaction_term(sim, run_->local_node(whole.node_address(n)), p.component));
    } else if (p.kind != ProbeSpec::Kind::BarForce && p.kind != ProbeSpec::Kind::Load &&
               p.kind != ProbeSpec::Kind::Platen &&
               p.kind != ProbeSpec::Kind::PlatenDisplacement) {
      const BuiltCase::Gauge& g = c_.probe_gauges[i];
      for (const auto* nodes : {&g.from, &g.to})
        for (index_t n : *nodes)
          if (node_owner(sub, whole, n) == sub.rank)
            out.push_back(
                probe_term(g, sim.displacement(run_->local_node(whole.node_address(n)))));
    }
  }
  close_list(out, at);
}

void DistributedBody::append_energy_rows(std::vector<double>& out) {
  const Simulation& sim = run_->sim();
  EnergyRows& rows = rows_;
  for (auto* v : {&rows.elastic, &rows.damage, &rows.fatigue, &rows.bar_keys, &rows.kinetic})
    v->clear();
  run_->append_owned_energy_rows(rows);
  // The exact sums this process adds up (work, twice the damping, the imposed-velocity DOF's
  // kinetic energy), then the row counts and rows.
  for (const ExactSum* e : {&sim.report_work(), &sim.report_twice_damping(),
                            &sim.report_condition_kinetic(), &sim.report_contact(),
                            &sim.ledger_state().friction}) {
    out.resize(out.size() + ExactSum::kDoubles);
    e->write(out.data() + out.size() - ExactSum::kDoubles);
  }
  out.push_back(static_cast<double>(rows.elastic.size()));
  out.push_back(static_cast<double>(rows.kinetic.size()));
  for (const auto* v : {&rows.elastic, &rows.damage, &rows.fatigue, &rows.kinetic})
    out.insert(out.end(), v->begin(), v->end());
}

void DistributedBody::append_events(std::vector<double>& out) {
  const Lattice& local = run_->sim().lattice();
  const std::size_t at = open_list(out);
  for (const Event& e : run_->sim().take_events()) {
    // Events of the ghost modules' bars are their owners' to report.
    if (!run_->owns_bar(e.bar))
      continue;
    out.push_back(global_bar(run_->subdomain(), local, lattice(), e.bar));
    out.push_back(static_cast<double>(e.state));
    out.push_back(static_cast<double>(e.step));
  }
  close_list(out, at);
}

void DistributedBody::read_report(bool report) {
  if (!writes())
    return;
  const std::vector<double>& all = received_;
  const Lattice& whole = lattice();
  const auto& probes = c_.spec.probes;
  // Per process, in rank order: its probe terms, its sums and energy rows, its events. The
  // bar rows of all processes, in rank order, visited in bar_order_ are the body's rows in
  // order.
  std::vector<const double*> probe_terms;
  std::vector<double> elastic_rows, damage_rows, fatigue_rows, kinetic_rows;
  ExactSum work, damping2, kinetic, contact, friction;
  std::vector<ExactSum> platen_forces; // per platen probe, in the probes' order
  std::size_t pos = 0;
  for (int r = 0; r < ranks_; ++r) {
    if (report) {
      probe_terms.push_back(all.data() + pos + 1);
      pos += 1 + static_cast<std::size_t>(all[pos]);
      std::size_t k = 0;
      for (const ProbeSpec& p : probes)
        if (p.kind == ProbeSpec::Kind::Platen) {
          if (platen_forces.size() <= k)
            platen_forces.emplace_back();
          ExactSum part;
          part.read(all.data() + pos);
          platen_forces[k++].add(part);
          pos += ExactSum::kDoubles;
        }
    }
    for (ExactSum* e : {&work, &damping2, &kinetic, &contact, &friction}) {
      ExactSum part;
      part.read(all.data() + pos);
      e->add(part);
      pos += ExactSum::kDoubles;
    }
    const auto nb = static_cast<std::size_t>(all[pos]);
    const auto nn = static_cast<std::size_t>(all[pos + 1]);
    const auto rows = all.begin() + static_cast<std::ptrdiff_t>(pos + 2);
    const auto b = static_cast<std::ptrdiff_t>(nb), n = static_cast<std::ptrdiff_t>(nn);
    elastic_rows.insert(elastic_rows.end(), rows, rows + b);
    damage_rows.insert(damage_rows.end(), rows + b, rows + 2 * b);
    fatigue_rows.insert(fatigue_rows.end(), rows + 2 * b, rows + 3 * b);
    kinetic_rows.insert(kinetic_rows.end(), rows + 3 * b, rows + 3 * b + n);
    pos += 2 + 3 * nb + nn;
    const auto ne = static_cast<std::size_t>(all[pos]);
    for (std::size_t q = pos + 1; q < pos + 1 + ne; q += 3)
      events_.push_back({static_cast<index_t>(all[q]), static_cast<BarState>(all[q + 1]),
                         static_cast<std::uint64_t>(all[q + 2])});
    pos += 1 + ne;
  }
  // From zero, row after row, as one process sums them; the kinetic energy exactly, as there.
  const double elastic = sum_in_order(elastic_rows, bar_order_);
  const double damage = sum_in_order(damage_rows, bar_order_);
  const double fatigue = sum_in_order(fatigue_rows, bar_order_);
  for (double x : kinetic_rows)
    kinetic.add(x);
  const double t = run_->sim().last_report().time;
  if (t == 0.0)
    initial_ = elastic + kinetic.value();
  report_ = energy_report(
      t, work.value(), elastic, kinetic.value(), damage, 0.5 * damping2.value(), initial_,
      balance_floor(numbers_.ranges.E[1], numbers_.ranges.e_p[1], lattice().volume()), fatigue,
      contact.value(), friction.value());
  if (!report)
    return;
  // Probes: the owner's bar force; a reaction's terms subtracted in the set's order, each
  // from the process that owns the node.
  const Subdomain& sub = run_->subdomain();
  probes_.assign(probes.size(), 0.0);
  std::size_t platen_probe = 0;
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ProbeSpec& p = probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce) {
      probes_[i] =
          *probe_terms[static_cast<std::size_t>(bar_owner(sub, whole, c_.probe_bars[i]))]++;
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      for (index_t n : set_named(c_.sets, p.set).nodes)
        probes_[i] -= *probe_terms[static_cast<std::size_t>(node_owner(sub, whole, n))]++;
    } else if (p.kind == ProbeSpec::Kind::Load) {
      probes_[i] = load_probe(p, t);
    } else if (p.kind == ProbeSpec::Kind::Platen) {
      probes_[i] = platen_forces[platen_probe++].value();
    } else if (p.kind == ProbeSpec::Kind::PlatenDisplacement) {
      // (After the step: its displacement at t_n is the one before the current.)
      probes_[i] = run_->sim().platen_positions()[6 * platen_index(p.platen) + 3 +
                                                  static_cast<std::size_t>(p.component)];
    } else {
      probes_[i] = gauge_from(c_.probe_gauges[i], probe_terms);
    }
  }
}

index_t DistributedBody::first_node_beyond(double limit) {
  const Simulation& sim = run_->sim();
  const index_t n = sim.first_node_beyond(limit);
  double global = lattice().num_nodes();
  if (n < sim.lattice().num_nodes()) {
    // The window's numbering keeps the body's order, so its first such node is the first of
    // the body's within the window.
    const NodeAddress a = run_->global_address(n);
    global = a.centre ? lattice().centre(a.i, a.j, a.k) : lattice().corner(a.i, a.j, a.k);
  }
  return static_cast<index_t>(min_over_processes(global));
}

int DistributedBody::max_over_processes(int value) const {
  return static_cast<int>(ldem::max_over_processes(static_cast<double>(value)));
}

void DistributedBody::prepare_snapshots() {
  vtu_ = std::make_unique<SubdomainVtuWriter>(*run_, lattice(), c_.spec.output.vtu_arrays,
                                              c_.spec.output.vtu_zlib);
}

void DistributedBody::write_snapshot(const std::string& path) {
  if (!vtu_)
    prepare_snapshots();
  vtu_->write(*run_, path);
}

std::vector<Span> DistributedBody::node_spans(bool owned) const {
  return subdomain_node_spans(run_->subdomain(), lattice(), owned);
}

std::vector<Span> DistributedBody::bar_spans(bool owned) const {
  return subdomain_bar_spans(run_->subdomain(), lattice(), owned);
}

Ledger::State DistributedBody::collect_ledger_and_events() {
  Ledger::State ledger = run_->sim().ledger_state();
  std::vector<double>& mine = send_;
  mine.assign(Ledger::State::kDoubles, 0.0);
  ledger.write(mine.data());
  append_events(mine); // those since the last report
  gather_on_first(mine, received_);
  if (!writes())
    return ledger;
  ledger = Ledger::State{{}, {}, {}, initial_};
  const double* in = received_.data();
  for (int r = 0; r < ranks_; ++r) {
    Ledger::State part;
    part.read(in);
    ledger.add(part);
    in += Ledger::State::kDoubles;
    const auto ne = static_cast<std::size_t>(in[0]);
    for (std::size_t q = 1; q + 2 <= ne; q += 3)
      events_.push_back({static_cast<index_t>(in[q]), static_cast<BarState>(in[q + 1]),
                         static_cast<std::uint64_t>(in[q + 2])});
    in += 1 + ne;
  }
  return ledger;
}

Vec3 DistributedBody::displacement(index_t node) {
  std::vector<double> mine;
  const NodeAddress a = lattice().node_address(node);
  if (owner_rank(run_->subdomain(), a.j, a.k) == rank_) {
    const Vec3 u = run_->sim().displacement(run_->local_node(a));
    mine = {u.x, u.y, u.z};
  }
  const std::vector<double> all = gather_on_first(mine);
  return all.size() == 3 ? Vec3{all[0], all[1], all[2]} : Vec3{0, 0, 0};
}

} // namespace

std::unique_ptr<RunBody> make_distributed_body(BuiltCase& c, ProcessGrid grid, int rank) {
  return std::make_unique<DistributedBody>(c, grid, rank);
}

} // namespace ldem
