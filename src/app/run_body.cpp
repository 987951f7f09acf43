#include "app/run_body.hpp"

#include "material/field.hpp"
#include "parallel/comm.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>

namespace ldem {

namespace {

const NodeSet& set_named(const std::vector<NodeSet>& sets, const std::string& name) {
  for (const NodeSet& s : sets)
    if (s.name == name)
      return s;
  throw InputError("node set \"" + name + "\" is not defined");
}

// A probe's value that needs no simulation: the total of a load at time t.
double load_probe(const BuiltCase& c, const ProbeSpec& p, double t) {
  for (const LoadSpec& l : c.spec.loads)
    if (l.name == p.load)
      return l.scale(t) *
             std::sqrt(l.force.x * l.force.x + l.force.y * l.force.y + l.force.z * l.force.z) *
             static_cast<double>(set_named(c.sets, l.set).nodes.size());
  return 0.0;
}

// The reaction probe's term of one node: its bar forces and load along the component (the
// reaction is minus their sum over the set).
double reaction_term(const Simulation& sim, index_t node, int component) {
  const Vec3 f = sim.node_force(node), l = sim.nodal_load(node);
  return component == 0 ? f.x + l.x : component == 1 ? f.y + l.y : f.z + l.z;
}

} // namespace

RunBody::RunBody(BuiltCase& c) : c_(c), dt_(c.sim->dt()) {
  report_ = c.sim->last_report();
}

RunBody::RunBody(BuiltCase& c, ProcessGrid grid, int rank)
    : c_(c), rank_(rank), ranks_(grid.py * grid.pz) {
  const Lattice& whole = *c.lattice;
  const Subdomain sub = make_subdomain(whole.ny(), whole.nz(), grid, rank);
  Lattice local = window_lattice(sub, whole);
  // The window's material: the body's fields evaluated at the window's bars and modules
  // (random draws by the body's numbers, correlated fields from the body's one grid), the
  // values the whole body has there.
  const CaseSpec::Fields& given = c.spec.fields;
  BarFields fields;
  std::vector<index_t> global_bars;
  if (given.E || given.Gf || given.e_p || given.e_r || given.R_f) {
    global_bars.resize(local.num_bars());
    for (index_t b = 0; b < local.num_bars(); ++b)
      global_bars[b] = global_bar(sub, local, whole, b);
  }
  const std::pair<const std::optional<Field>*, std::vector<double>*> props[] = {
      {&given.E, &fields.E},
      {&given.Gf, &fields.Gf},
      {&given.e_p, &fields.e_p},
      {&given.e_r, &fields.e_r},
      {&given.R_f, &fields.R_f}};
  for (const auto& [field, values] : props)
    if (*field)
      *values = evaluate_field(**field, whole, global_bars);
  if (given.rho) { // the window's modules (i, j, k), numbered i + nx (j + ny k) in the body
    std::vector<index_t> modules;
    modules.reserve(local.num_modules());
    for (index_t k = sub.z.w0; k < sub.z.w1; ++k)
      for (index_t j = sub.y.w0; j < sub.y.w1; ++j)
        for (index_t i = 0; i < whole.nx(); ++i)
          modules.push_back(i + whole.nx() * (j + whole.ny() * k));
    fields.rho = evaluate_field_modules(*given.rho, whole, modules);
  }
  BarTable table(local, c.spec.material, fields);
  Conditions conditions = subdomain_conditions(sub, whole, local, c.conditions);
  std::vector<index_t> precracked;
  for (index_t b : c.precracked) {
    const BarAddress a = whole.bar_address(b);
    const FamilyInfo& fl = local.family(a.family);
    if (a.j >= sub.y.w0 && a.j - sub.y.w0 < fl.nj && a.k >= sub.z.w0 && a.k - sub.z.w0 < fl.nk)
      precracked.push_back(local.bar(a.family, a.i, a.j - sub.y.w0, a.k - sub.z.w0));
  }
  std::sort(precracked.begin(), precracked.end());
  SolverOptions options = c.options;
  options.defer_time_step = true; // the body's step, below
  run_ = std::make_unique<SubdomainRun>(sub, std::move(local), std::move(table),
                                        std::move(conditions), options, std::move(precracked));
  // The body's stable step and dt, as one process finds them: the stiffest material of all
  // windows for the paper's rule.
  stable_ = distributed_stable_step(*run_, whole);
  const double E_max = ldem::max_over_processes(run_->sim().table().ranges().E[1]);
  dt_ =
      time_step_by_rule(c.options.step, stable_, E_max, run_->sim().table().spec().rho, whole.L());
  run_->sim().set_time_step(stable_, dt_);
  // The place of every process's energy rows in the body's order, found once: the rows of a
  // report come in rank order, each process's in its own order.
  EnergyRows rows;
  run_->append_owned_row_keys(rows);
  bar_order_ = key_order(gather_on_first(rows.bar_keys));
}

std::uint64_t RunBody::step_count() const {
  return run_ ? run_->sim().step_count() : c_.sim->step_count();
}

void RunBody::step(bool report) {
  if (!run_) {
    if (report)
      probes_ = serial_probes();
    c_.sim->step(report);
    if (report)
      report_ = c_.sim->last_report();
    return;
  }
  const bool first_step = run_->sim().step_count() == 0; // energies are computed at step 0
  send_.clear();
  if (report)
    append_probe_terms(send_);
  run_->sim().step(report);
  exchange_halos(*run_, halo_);
  if (!report && !first_step)
    return;
  append_energy_rows(send_);
  append_events(send_);
  gather_on_first(send_, received_);
  read_report(report);
}

std::vector<double> RunBody::serial_probes() const {
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
    else
      values[i] = load_probe(c_, p, sim.time());
  }
  return values;
}

namespace {

int node_owner(const Subdomain& any, const Lattice& whole, index_t node) {
  const NodeAddress a = whole.node_address(node);
  return owner_rank(any, a.j, a.k);
}

int bar_owner(const Subdomain& any, const Lattice& whole, index_t bar) {
  const BarAddress a = whole.bar_address(bar);
  return owner_rank(any, a.j, a.k);
}

// Appends a list's length, then reserves it: returns the length's place, to be set.
std::size_t open_list(std::vector<double>& out) {
  out.push_back(0.0);
  return out.size() - 1;
}
void close_list(std::vector<double>& out, std::size_t at) {
  out[at] = static_cast<double>(out.size() - at - 1);
}

} // namespace

void RunBody::append_probe_terms(std::vector<double>& out) const {
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
    }
  }
  close_list(out, at);
}

void RunBody::append_energy_rows(std::vector<double>& out) {
  const Simulation& sim = run_->sim();
  EnergyRows& rows = rows_;
  for (auto* v : {&rows.elastic, &rows.damage, &rows.bar_keys, &rows.kinetic})
    v->clear();
  run_->append_owned_energy_rows(rows);
  // The exact sums this process adds up (work, twice the damping, the imposed-velocity DOF's
  // kinetic energy), then the row counts and rows.
  for (const ExactSum* e :
       {&sim.report_work(), &sim.report_twice_damping(), &sim.report_condition_kinetic()}) {
    out.resize(out.size() + ExactSum::kDoubles);
    e->write(out.data() + out.size() - ExactSum::kDoubles);
  }
  out.push_back(static_cast<double>(rows.elastic.size()));
  out.push_back(static_cast<double>(rows.kinetic.size()));
  for (const auto* v : {&rows.elastic, &rows.damage, &rows.kinetic})
    out.insert(out.end(), v->begin(), v->end());
}

void RunBody::append_events(std::vector<double>& out) {
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

void RunBody::read_report(bool report) {
  if (!writes())
    return;
  const std::vector<double>& all = received_;
  const Lattice& whole = lattice();
  const auto& probes = c_.spec.probes;
  // Per process, in rank order: its probe terms, its sums and energy rows, its events. The
  // bar rows of all processes, in rank order, visited in bar_order_ are the body's rows in
  // order.
  std::vector<const double*> probe_terms;
  std::vector<double> elastic_rows, damage_rows, kinetic_rows;
  ExactSum work, damping2, kinetic;
  std::size_t pos = 0;
  for (int r = 0; r < ranks_; ++r) {
    if (report) {
      probe_terms.push_back(all.data() + pos + 1);
      pos += 1 + static_cast<std::size_t>(all[pos]);
    }
    for (ExactSum* e : {&work, &damping2, &kinetic}) {
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
    kinetic_rows.insert(kinetic_rows.end(), rows + 2 * b, rows + 2 * b + n);
    pos += 2 + 2 * nb + nn;
    const auto ne = static_cast<std::size_t>(all[pos]);
    for (std::size_t q = pos + 1; q < pos + 1 + ne; q += 3)
      events_.push_back({static_cast<index_t>(all[q]), static_cast<BarState>(all[q + 1]),
                         static_cast<std::uint64_t>(all[q + 2])});
    pos += 1 + ne;
  }
  // From zero, row after row, as one process sums them; the kinetic energy exactly, as there.
  const double elastic = sum_in_order(elastic_rows, bar_order_);
  const double damage = sum_in_order(damage_rows, bar_order_);
  for (double x : kinetic_rows)
    kinetic.add(x);
  const double t = run_->sim().last_report().time;
  if (t == 0.0)
    initial_ = elastic + kinetic.value();
  report_ = energy_report(t, work.value(), elastic, kinetic.value(), damage, 0.5 * damping2.value(),
                          initial_);
  if (!report)
    return;
  // Probes: the owner's bar force; a reaction's terms subtracted in the set's order, each
  // from the process that owns the node.
  const Subdomain& sub = run_->subdomain();
  probes_.assign(probes.size(), 0.0);
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ProbeSpec& p = probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce) {
      probes_[i] =
          *probe_terms[static_cast<std::size_t>(bar_owner(sub, whole, c_.probe_bars[i]))]++;
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      for (index_t n : set_named(c_.sets, p.set).nodes)
        probes_[i] -= *probe_terms[static_cast<std::size_t>(node_owner(sub, whole, n))]++;
    } else {
      probes_[i] = load_probe(c_, p, t);
    }
  }
}

std::vector<Event> RunBody::take_events() {
  if (!run_)
    return c_.sim->take_events();
  if (!writes())
    return {};
  std::vector<Event> events = c_.sim->take_events(); // any left from a checkpoint
  events.insert(events.end(), events_.begin(), events_.end());
  events_.clear();
  std::sort(events.begin(), events.end(), event_before);
  return events;
}

index_t RunBody::first_node_beyond(double limit) {
  if (!run_)
    return c_.sim->first_node_beyond(limit);
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

int RunBody::max_over_processes(int value) const {
  return static_cast<int>(ldem::max_over_processes(static_cast<double>(value)));
}

Simulation* RunBody::whole(bool full) {
  if (!run_)
    return c_.sim.get();
  const Simulation& sim = run_->sim();
  const Lattice& body = lattice();
  std::vector<double>& mine = send_;
  mine.clear();
  for (bool previous : {false, true}) // u_{n-1} too: snapshots show velocities
    for (const Span& s : subdomain_node_spans(run_->subdomain(), body, true))
      sim.append_displacements(s.local_first, s.count, mine, previous);
  for (const Span& s : subdomain_bar_spans(run_->subdomain(), body, true))
    sim.append_histories(s.local_first, s.count, mine);
  mine.resize(mine.size() + Ledger::State::kDoubles);
  sim.ledger_state().write(mine.data() + mine.size() - Ledger::State::kDoubles);
  if (full)
    append_events(mine); // those since the last report
  gather_on_first(mine, received_);
  if (!writes())
    return nullptr;
  Simulation& w = *c_.sim;
  const double* in = received_.data();
  Ledger::State ledger; // the processes' accumulators, added exactly
  for (int r = 0; r < ranks_; ++r) {
    const Subdomain sub = make_subdomain(body.ny(), body.nz(), run_->subdomain().grid, r);
    for (bool previous : {false, true})
      for (const Span& s : subdomain_node_spans(sub, body, true)) {
        w.assign_displacements(s.global_first, s.count, in, previous);
        in += 3 * std::size_t{s.count};
      }
    for (const Span& s : subdomain_bar_spans(sub, body, true)) {
      w.assign_histories(s.global_first, s.count, in);
      in += s.count;
    }
    Ledger::State part;
    part.read(in);
    ledger.add(part);
    in += Ledger::State::kDoubles;
    if (full) {
      const auto ne = static_cast<std::size_t>(in[0]);
      for (std::size_t q = 1; q + 2 <= ne; q += 3)
        events_.push_back({static_cast<index_t>(in[q]), static_cast<BarState>(in[q + 1]),
                           static_cast<std::uint64_t>(in[q + 2])});
      in += 1 + ne;
    }
  }
  std::vector<Event> pending = take_events(); // a checkpoint keeps those not yet written
  ledger.initial = initial_;
  w.restore_progress(step_count(), full ? ledger : w.ledger_state(), report_, std::move(pending));
  return &w;
}

void RunBody::prepare_snapshots() {
  if (run_)
    subdomain_vtu_ = std::make_unique<SubdomainVtuWriter>(*run_, lattice());
  else
    vtu_ = std::make_unique<LatticeVtuWriter>(*c_.sim);
}

void RunBody::write_snapshot(const std::string& path) {
  if (!vtu_ && !subdomain_vtu_)
    prepare_snapshots();
  if (run_)
    subdomain_vtu_->write(*run_, path);
  else
    vtu_->write(*c_.sim, path);
}

void RunBody::spread_whole_state() {
  if (!run_)
    return;
  const Lattice& body = lattice();
  std::vector<std::vector<double>> parts;
  double progress[1 + Ledger::State::kDoubles] = {}; // the step, the body's ledger
  if (writes()) {
    const Simulation& w = *c_.sim;
    for (int r = 0; r < ranks_; ++r) {
      const Subdomain sub = make_subdomain(body.ny(), body.nz(), run_->subdomain().grid, r);
      std::vector<double> part;
      for (bool previous : {false, true})
        for (const Span& s : subdomain_node_spans(sub, body, false))
          w.append_displacements(s.global_first, s.count, part, previous);
      for (const Span& s : subdomain_bar_spans(sub, body, false))
        w.append_histories(s.global_first, s.count, part);
      parts.push_back(std::move(part));
    }
    progress[0] = static_cast<double>(w.step_count());
    w.ledger_state().write(progress + 1);
    report_ = w.last_report();
  }
  const std::vector<double> part = scatter_from_first(parts);
  broadcast_from_first(progress, 1 + Ledger::State::kDoubles);
  Simulation& sim = run_->sim();
  const double* in = part.data();
  for (bool previous : {false, true})
    for (const Span& s : subdomain_node_spans(run_->subdomain(), body, false)) {
      sim.assign_displacements(s.local_first, s.count, in, previous);
      in += 3 * std::size_t{s.count};
    }
  for (const Span& s : subdomain_bar_spans(run_->subdomain(), body, false)) {
    sim.assign_histories(s.local_first, s.count, in);
    in += s.count;
  }
  Ledger::State ledger;
  ledger.read(progress + 1);
  initial_ = ledger.initial;
  // The body's accumulated work and damping go to the first process; the others add from zero.
  if (!writes())
    ledger = Ledger::State{{}, {}, initial_};
  sim.restore_progress(static_cast<std::uint64_t>(progress[0]), ledger, {}, {});
}

} // namespace ldem
