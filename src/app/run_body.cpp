#include "app/run_body.hpp"

#include "io/checkpoint.hpp"
#include "material/field.hpp"
#include "parallel/comm.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <numeric>
#include <optional>

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
    throw InputError(fmt::format("{}: {}", c.path, e.what()));
  }
  BarTable& table = *table_built;
  numbers_.ranges = table.ranges();
  numbers_.ductility = table.ductility_summary();
  numbers_.per_bar = table.per_bar();
  if (rank == 0)
    c.warnings = table.warnings(); // those of the case's values (the same on every process)
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
}

void RunBody::agree_on_body() {
  if (!run_)
    return;
  const Lattice& whole = lattice();
  const BuiltCase& c = c_;
  const Subdomain& sub = run_->subdomain();
  // The body's material summary, stable step and dt, as one process finds them.
  try {
    combine_numbers(whole);
    stable_ = distributed_stable_step(*run_, whole);
    dt_ = time_step_by_rule(c.options.step, stable_, numbers_.ranges.E[1],
                            run_->sim().table().spec().rho, whole.L());
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", c.path, e.what()));
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

void RunBody::combine_numbers(const Lattice& whole) {
  // The body's ranges and ductility from every process's owned bars: smallest of the
  // smallest, largest of the largest, counts added; the worst bar the body's first with the
  // smallest K_r.
  MaterialRanges& r = numbers_.ranges;
  for (double* range : {r.E, r.Gf, r.e_p, r.e_r_normal}) {
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

BodyNumbers RunBody::numbers() const {
  return run_ ? numbers_ : body_numbers(*c_.sim);
}

void RunBody::write_fields(const std::string& path) {
  // Every bar up to 2 million, else every stride-th: each with its centre and material as a
  // user reads them (BarTable::properties).
  const Lattice& whole = lattice();
  const index_t stride = std::max<index_t>(1, whole.num_bars() / 2000000 + 1);
  std::vector<double> rows; // (bar, E, Gf, e_p, e_r) of the sampled bars this process owns
  if (!run_) {
    for (index_t b = 0; b < whole.num_bars(); b += stride) {
      const BarTable::Properties p = c_.sim->table().properties(whole, b);
      rows.insert(rows.end(), {static_cast<double>(b), p.E, p.Gf, p.e_p, p.e_r});
    }
  } else {
    const Lattice& local = run_->sim().lattice();
    for (index_t b = 0; b < local.num_bars(); ++b) {
      const index_t g = global_bar(run_->subdomain(), local, whole, b);
      if (g % stride != 0 || !run_->owns_bar(b))
        continue;
      const BarTable::Properties p = run_->sim().table().properties(local, b);
      rows.insert(rows.end(), {static_cast<double>(g), p.E, p.Gf, p.e_p, p.e_r});
    }
    rows = gather_on_first(rows);
  }
  if (!writes())
    return;
  // In the body's order (the processes' rows come in rank order).
  std::vector<std::size_t> order(rows.size() / 5);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return rows[5 * a] < rows[5 * b]; });
  OutputFile file(path);
  file.write("bar,x,y,z,E,Gf,e_p,e_r\n");
  std::string text;
  for (std::size_t q : order) {
    const double* row = rows.data() + 5 * q;
    const auto b = static_cast<index_t>(row[0]);
    const Vec3 mid = whole.bar_centre(b);
    text += fmt::format("{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", b, mid.x, mid.y,
                        mid.z, row[1], row[2], row[3], row[4]);
    if (text.size() > (1u << 20)) {
      file.write(text);
      text.clear();
    }
  }
  file.write(text);
  file.commit();
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
  // Those left from a checkpoint (or kept by one), then the newer ones.
  std::vector<Event> events = std::move(events_);
  events_.clear();
  if (!run_) {
    const std::vector<Event> more = c_.sim->take_events();
    events.insert(events.end(), more.begin(), more.end());
  }
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

Simulation& RunBody::sim() {
  return run_ ? run_->sim() : *c_.sim;
}

std::vector<Span> RunBody::node_spans(bool owned) const {
  if (run_)
    return subdomain_node_spans(run_->subdomain(), lattice(), owned);
  return {{0, 0, lattice().num_nodes()}};
}

template <class F> void RunBody::for_each_owned_piece(F&& visit) {
  // u_n and u_{n-1}, x, y and z (arrays 0 to 5 of the body's nodes), then the histories (after
  // them): a piece per span of owned nodes or bars.
  const std::uint64_t nodes = lattice().num_nodes();
  std::vector<double>& buf = send_;
  for (bool previous : {false, true})
    for (const Span& s : node_spans(true)) {
      buf.clear();
      sim().append_displacements(s.local_first, s.count, buf, previous);
      for (std::uint64_t d = 0; d < 3; ++d)
        visit(((previous ? 3 : 0) + d) * nodes + s.global_first, buf.data() + d * s.count, s.count);
    }
  for (const Span& s : bar_spans(true)) {
    buf.clear();
    sim().append_bar_states(0, s.local_first, s.count, buf);
    visit(6 * nodes + s.global_first, buf.data(), s.count);
  }
}

std::vector<Span> RunBody::bar_spans(bool owned) const {
  if (run_)
    return subdomain_bar_spans(run_->subdomain(), lattice(), owned);
  return {{0, 0, lattice().num_bars()}};
}

void RunBody::write_checkpoint(const std::string& path, const std::string& meta) {
  namespace ck = checkpoint;
  // The body's ledger (every process's exact sums added) and every event not yet written, on
  // the first process.
  Ledger::State ledger = sim().ledger_state();
  if (run_) {
    std::vector<double>& mine = send_;
    mine.assign(Ledger::State::kDoubles, 0.0);
    ledger.write(mine.data());
    append_events(mine); // those since the last report
    gather_on_first(mine, received_);
    if (writes()) {
      ledger = Ledger::State{{}, {}, initial_};
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
    }
  } else {
    const std::vector<Event> more = c_.sim->take_events();
    events_.insert(events_.end(), more.begin(), more.end());
  }
  std::sort(events_.begin(), events_.end(), event_before); // (kept: written at the next report)
  const Lattice& body = lattice();
  const std::uint64_t nodes = body.num_nodes(), bars = body.num_bars();
  std::string progress;
  std::uint64_t sum = 0;
  if (writes()) {
    ck::put(progress, step_count());
    ck::put(progress, dt_);
    double state[Ledger::State::kDoubles];
    ledger.write(state);
    ck::put(progress, state);
    ck::put(progress, report_);
    ck::put(progress, nodes);
    ck::put(progress, bars);
    ck::put(progress, static_cast<std::uint64_t>(events_.size()));
    for (const Event& e : events_) {
      ck::put(progress, e.bar);
      ck::put(progress, e.state);
      ck::put(progress, e.step);
    }
    sum = ck::fnv1a(meta.data(), meta.size()) + ck::fnv1a(progress.data(), progress.size());
  }
  double sizes[2] = {static_cast<double>(meta.size()), static_cast<double>(progress.size())};
  broadcast_from_first(sizes, 2);
  const std::uint64_t at = ck::Header::arrays_offset(static_cast<std::uint64_t>(sizes[0]),
                                                     static_cast<std::uint64_t>(sizes[1]));
  SharedFile file(path);
  for_each_owned_piece([&](std::uint64_t place, const double* v, index_t count) {
    for (index_t i = 0; i < count; ++i)
      sum += ck::word_hash(place + i, v[i]);
    file.write_at(at + 8 * place, v, 8 * std::size_t{count});
  });
  sum = wrapping_sum_over_processes(sum);
  if (writes()) {
    const std::string head = ck::header_bytes(meta, progress, sum) + meta + progress;
    file.write_at(0, head.data(), head.size());
    const std::string pad(at - head.size(), '\0');
    file.write_at(head.size(), pad.data(), pad.size());
  }
  file.commit();
}

std::string RunBody::read_checkpoint(const std::string& path) {
  namespace ck = checkpoint;
  const ck::Header h = ck::read_header(path);
  const Lattice& body = lattice();
  const std::uint64_t nodes = body.num_nodes(), bars = body.num_bars();
  std::size_t pos = 0;
  std::uint64_t step = 0, file_nodes = 0, file_bars = 0, pending = 0;
  double dt = 0.0, state[Ledger::State::kDoubles];
  EnergyReport report{};
  ck::get(h.progress, pos, step);
  ck::get(h.progress, pos, dt);
  ck::get(h.progress, pos, state);
  ck::get(h.progress, pos, report);
  ck::get(h.progress, pos, file_nodes);
  ck::get(h.progress, pos, file_bars);
  if (file_nodes != nodes || file_bars != bars)
    throw InputError(fmt::format("{}: a checkpoint of a body of {} nodes and {} bars; this case "
                                 "has {} and {}",
                                 path, file_nodes, file_bars, nodes, bars));
  if (dt != dt_)
    throw InputError(fmt::format("{}: its time step {:.17g} s differs from this case's {:.17g} s",
                                 path, dt, dt_));
  const std::uint64_t at = h.arrays_at(), expected = at + 8 * (6 * nodes + bars);
  if (h.file_bytes != expected)
    throw InputError(fmt::format("{}: truncated checkpoint ({} bytes, {} expected)", path,
                                 h.file_bytes, expected));
  std::vector<Event> events;
  ck::get(h.progress, pos, pending);
  for (std::uint64_t i = 0; i < pending; ++i) {
    Event e{};
    ck::get(h.progress, pos, e.bar);
    ck::get(h.progress, pos, e.state);
    ck::get(h.progress, pos, e.step);
    events.push_back(e);
  }
  // The window's nodes and bars (owned and ghosts), each value from its place.
  std::ifstream in(path, std::ios::binary);
  std::vector<double>& buf = send_;
  auto read_piece = [&](std::uint64_t place, double* v, index_t count) {
    in.seekg(static_cast<std::streamoff>(at + 8 * place));
    if (!in.read(reinterpret_cast<char*>(v), static_cast<std::streamsize>(8 * std::size_t{count})))
      throw InputError(fmt::format("{}: cannot read the checkpoint", path));
  };
  Simulation& s = sim();
  for (bool previous : {false, true})
    for (const Span& sp : node_spans(false)) {
      buf.resize(3 * std::size_t{sp.count});
      for (std::uint64_t d = 0; d < 3; ++d)
        read_piece(((previous ? 3 : 0) + d) * nodes + sp.global_first, buf.data() + d * sp.count,
                   sp.count);
      s.assign_displacements(sp.local_first, sp.count, buf.data(), previous);
    }
  for (const Span& sp : bar_spans(false)) {
    buf.resize(sp.count);
    read_piece(6 * nodes + sp.global_first, buf.data(), sp.count);
    s.assign_bar_states(0, sp.local_first, sp.count, buf.data());
  }
  // The checksum: every process adds the terms of what it owns.
  std::uint64_t sum = writes() ? ck::fnv1a(h.meta.data(), h.meta.size()) +
                                     ck::fnv1a(h.progress.data(), h.progress.size())
                               : 0;
  for_each_owned_piece([&](std::uint64_t place, const double* v, index_t count) {
    for (index_t i = 0; i < count; ++i)
      sum += ck::word_hash(place + i, v[i]);
  });
  if (wrapping_sum_over_processes(sum) != h.checksum)
    throw InputError(fmt::format("{}: checkpoint checksum mismatch: the file is corrupt", path));
  Ledger::State ledger;
  ledger.read(state);
  initial_ = ledger.initial;
  // The body's accumulated work and damping go to the first process; the others add from zero.
  if (!writes())
    ledger = Ledger::State{{}, {}, initial_};
  s.restore_progress(step, ledger, report, {});
  report_ = report;
  events_ = writes() ? std::move(events) : std::vector<Event>{};
  return h.meta;
}

std::array<std::uint64_t, 2> RunBody::softening_and_broken() {
  double counts[2] = {0, 0};
  const Simulation& s = sim();
  for (const Span& sp : bar_spans(true))
    for (index_t b = sp.local_first; b < sp.local_first + sp.count; ++b) {
      const BarState state = s.bar_state(b);
      counts[0] += state == BarState::Softening;
      counts[1] += state == BarState::Broken;
    }
  return {static_cast<std::uint64_t>(sum_over_processes(counts[0])),
          static_cast<std::uint64_t>(sum_over_processes(counts[1]))};
}

Vec3 RunBody::displacement(index_t node) {
  if (!run_)
    return c_.sim->displacement(node);
  std::vector<double> mine;
  const NodeAddress a = lattice().node_address(node);
  if (owner_rank(run_->subdomain(), a.j, a.k) == rank_) {
    const Vec3 u = run_->sim().displacement(run_->local_node(a));
    mine = {u.x, u.y, u.z};
  }
  const std::vector<double> all = gather_on_first(mine);
  return all.size() == 3 ? Vec3{all[0], all[1], all[2]} : Vec3{0, 0, 0};
}

} // namespace ldem
