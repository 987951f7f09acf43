#include "app/run_body.hpp"

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

// The order of Simulation::take_events.
void sort_events(std::vector<Event>& events) {
  std::sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
    if (a.step != b.step)
      return a.step < b.step;
    if (a.bar != b.bar)
      return a.bar < b.bar;
    return a.state < b.state;
  });
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

// A per-bar field of the body restricted to the window's bars (empty stays empty).
std::vector<double> window_values(const std::vector<double>& whole,
                                  const std::vector<index_t>& global_bars) {
  std::vector<double> v;
  if (whole.empty())
    return v;
  v.reserve(global_bars.size());
  for (index_t b : global_bars)
    v.push_back(whole[b]);
  return v;
}

} // namespace

RunBody::RunBody(BuiltCase& c) : c_(c), dt_(c.sim->dt()) {
  report_ = c.sim->last_report();
}

RunBody::RunBody(BuiltCase& c, int ranks, int rank) : c_(c), rank_(rank), ranks_(ranks) {
  double dt = c.sim ? c.sim->dt() : 0.0;
  broadcast_from_first(&dt, 1);
  dt_ = dt;
  const Lattice& whole = *c.lattice;
  const Slab slab = make_slab(whole.nz(), ranks, rank);
  Lattice local = window_lattice(slab, whole);
  // The window's material: the body's per-bar values of the same bars, the body's densities
  // of the same modules (the window's modules are the body's from module plane w0 on).
  std::vector<index_t> global_bars(local.num_bars());
  for (index_t b = 0; b < local.num_bars(); ++b)
    global_bars[b] = global_bar(slab, local, whole, b);
  BarFields fields;
  fields.E = window_values(c.fields.E, global_bars);
  fields.Gf = window_values(c.fields.Gf, global_bars);
  fields.e_p = window_values(c.fields.e_p, global_bars);
  fields.e_r = window_values(c.fields.e_r, global_bars);
  fields.R_f = window_values(c.fields.R_f, global_bars);
  if (!c.fields.rho.empty()) {
    const std::size_t first = std::size_t{whole.nx()} * whole.ny() * slab.w0;
    fields.rho.assign(c.fields.rho.begin() + static_cast<std::ptrdiff_t>(first),
                      c.fields.rho.begin() +
                          static_cast<std::ptrdiff_t>(first + local.num_modules()));
  }
  BarTable table(local, c.spec.material, fields);
  Conditions conditions = slab_conditions(slab, whole, local, c.conditions);
  std::vector<index_t> precracked;
  for (index_t b : c.precracked) {
    const BarAddress a = whole.bar_address(b);
    if (a.k >= slab.w0 && a.k - slab.w0 < local.family(a.family).nk)
      precracked.push_back(local.bar(a.family, a.i, a.j, a.k - slab.w0));
  }
  std::sort(precracked.begin(), precracked.end());
  run_ = std::make_unique<SlabRun>(slab, std::move(local), std::move(table),
                                   std::move(conditions), c.options, std::move(precracked));
  run_->sim().set_time_step(dt_);
}

std::uint64_t RunBody::step_count() const {
  return run_ ? run_->sim().step_count() : c_.sim->step_count();
}

void RunBody::step(bool report) {
  if (!run_) {
    c_.sim->step(report);
    if (report)
      report_ = c_.sim->last_report();
    return;
  }
  const bool first_step = run_->sim().step_count() == 0; // energies are computed at step 0
  run_->sim().step(report);
  exchange_halos(*run_, halo_);
  if (report || first_step)
    add_report();
}

void RunBody::add_report() {
  const Simulation& sim = run_->sim();
  std::vector<double> rows[3];
  run_->append_owned_energy_rows(rows[0], rows[1], rows[2]);
  const EnergyReport& r = sim.last_report();
  std::vector<double> mine = {r.external_work, r.damping_dissipated,
                              sim.report_condition_kinetic(), static_cast<double>(rows[0].size()),
                              static_cast<double>(rows[2].size())};
  for (const auto& v : rows)
    mine.insert(mine.end(), v.begin(), v.end());
  const std::vector<double> all = gather_on_first(mine);
  if (!writes())
    return;
  // Per slab: its sums, then its elastic, dissipated and kinetic rows. The rows of all
  // slabs in rank order are the body's rows in order.
  std::vector<double> elastic_rows, damage_rows, kinetic_rows;
  double work = 0.0, damping = 0.0, kinetic = 0.0;
  for (std::size_t pos = 0; pos < all.size();) {
    work += all[pos];
    damping += all[pos + 1];
    kinetic += all[pos + 2];
    const auto nb = static_cast<std::size_t>(all[pos + 3]), nn = static_cast<std::size_t>(all[pos + 4]);
    pos += 5;
    elastic_rows.insert(elastic_rows.end(), all.begin() + pos, all.begin() + pos + nb);
    damage_rows.insert(damage_rows.end(), all.begin() + pos + nb, all.begin() + pos + 2 * nb);
    kinetic_rows.insert(kinetic_rows.end(), all.begin() + pos + 2 * nb,
                        all.begin() + pos + 2 * nb + nn);
    pos += 2 * nb + nn;
  }
  // From zero, row after row, as one process sums them (the kinetic energy after the
  // imposed-velocity DOF's, as there).
  double elastic = 0.0, damage = 0.0;
  for (double x : elastic_rows)
    elastic += x;
  for (double x : damage_rows)
    damage += x;
  for (double x : kinetic_rows)
    kinetic += x;
  if (r.time == 0.0)
    initial_ = elastic + kinetic;
  Ledger ledger;
  ledger.set_state({work, damping, initial_});
  report_ = ledger.report(r.time, elastic, kinetic, damage, 0.0, 0.0);
}

std::vector<Event> RunBody::take_events() {
  if (!run_)
    return c_.sim->take_events();
  const Slab& slab = run_->slab();
  const Lattice& local = run_->sim().lattice();
  std::vector<double> mine;
  for (const Event& e : run_->sim().take_events()) {
    // Events of the ghost module's bars are their owner's to report.
    if (!slab.owns_plane(local.bar_address(e.bar).k + slab.w0, true))
      continue;
    mine.push_back(global_bar(slab, local, lattice(), e.bar));
    mine.push_back(static_cast<double>(e.state));
    mine.push_back(static_cast<double>(e.step));
  }
  const std::vector<double> all = gather_on_first(mine);
  if (!writes())
    return {};
  std::vector<Event> events = c_.sim->take_events(); // any left from a checkpoint
  for (std::size_t i = 0; i + 2 < all.size(); i += 3)
    events.push_back({static_cast<index_t>(all[i]), static_cast<BarState>(all[i + 1]),
                      static_cast<std::uint64_t>(all[i + 2])});
  sort_events(events);
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

std::vector<double> RunBody::probe_values() {
  const auto& probes = c_.spec.probes;
  std::vector<double> values(probes.size(), 0.0);
  if (!run_) {
    const Simulation& sim = *c_.sim;
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
  // Each slab evaluates what it owns: the probed bar, the set's nodes (in the set's order).
  const Lattice& whole = lattice();
  const auto owner = [&](const Slab& slab, index_t node) {
    const NodeAddress a = whole.node_address(node);
    return slab.owns_plane(a.k, !a.centre);
  };
  const auto owns_bar = [&](const Slab& slab, index_t bar) {
    return slab.owns_plane(whole.bar_address(bar).k, true);
  };
  const Slab& mine_slab = run_->slab();
  const Simulation& sim = run_->sim();
  std::vector<double> mine;
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ProbeSpec& p = probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce && owns_bar(mine_slab, c_.probe_bars[i])) {
      const BarAddress a = whole.bar_address(c_.probe_bars[i]);
      mine.push_back(
          sim.bar_force(sim.lattice().bar(a.family, a.i, a.j, a.k - mine_slab.w0)));
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      for (index_t n : set_named(c_.sets, p.set).nodes)
        if (owner(mine_slab, n))
          mine.push_back(reaction_term(sim, run_->local_node(whole.node_address(n)), p.component));
    }
  }
  const std::vector<double> all = gather_on_first(mine);
  if (!writes())
    return values;
  // Slab p's values, probe by probe, start at from[p][i].
  std::vector<Slab> slabs;
  for (int r = 0; r < ranks_; ++r)
    slabs.push_back(make_slab(whole.nz(), ranks_, r));
  std::vector<std::vector<std::size_t>> from(slabs.size(), std::vector<std::size_t>(probes.size()));
  std::size_t pos = 0;
  for (std::size_t r = 0; r < slabs.size(); ++r)
    for (std::size_t i = 0; i < probes.size(); ++i) {
      from[r][i] = pos;
      const ProbeSpec& p = probes[i];
      if (p.kind == ProbeSpec::Kind::BarForce)
        pos += owns_bar(slabs[r], c_.probe_bars[i]) ? 1 : 0;
      else if (p.kind == ProbeSpec::Kind::Reaction)
        for (index_t n : set_named(c_.sets, p.set).nodes)
          pos += owner(slabs[r], n) ? 1 : 0;
    }
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ProbeSpec& p = probes[i];
    if (p.kind == ProbeSpec::Kind::BarForce) {
      for (std::size_t r = 0; r < slabs.size(); ++r)
        if (owns_bar(slabs[r], c_.probe_bars[i]))
          values[i] = all[from[r][i]];
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      for (index_t n : set_named(c_.sets, p.set).nodes) // the set's order, as one process
        for (std::size_t r = 0; r < slabs.size(); ++r)
          if (owner(slabs[r], n))
            values[i] -= all[from[r][i]++];
    } else {
      values[i] = load_probe(c_, p, time());
    }
  }
  return values;
}

int RunBody::max_over_processes(int value) const {
  return static_cast<int>(ldem::max_over_processes(static_cast<double>(value)));
}

Simulation* RunBody::whole(bool full) {
  if (!run_)
    return c_.sim.get();
  std::vector<Event> pending;
  if (full)
    pending = take_events(); // collective; the whole body's on the first process
  const Simulation& sim = run_->sim();
  const Lattice& body = lattice();
  std::vector<double> mine;
  for (bool previous : {false, true}) // u_{n-1} too: snapshots show velocities
    for (const Span& s : slab_node_spans(run_->slab(), body, true))
      sim.append_displacements(s.local_first, s.count, mine, previous);
  for (const Span& s : slab_bar_spans(run_->slab(), body, true))
    sim.append_histories(s.local_first, s.count, mine);
  const std::array<double, 3> ledger = sim.ledger_state();
  mine.push_back(ledger[0]);
  mine.push_back(ledger[1]);
  const std::vector<double> all = gather_on_first(mine);
  if (!writes())
    return nullptr;
  Simulation& w = *c_.sim;
  const double* in = all.data();
  double work = 0.0, damping = 0.0;
  for (int r = 0; r < ranks_; ++r) {
    const Slab slab = make_slab(body.nz(), ranks_, r);
    for (bool previous : {false, true})
      for (const Span& s : slab_node_spans(slab, body, true)) {
        w.assign_displacements(s.global_first, s.count, in, previous);
        in += 3 * std::size_t{s.count};
      }
    for (const Span& s : slab_bar_spans(slab, body, true)) {
      w.assign_histories(s.global_first, s.count, in);
      in += s.count;
    }
    work += in[0];
    damping += in[1];
    in += 2;
  }
  if (!full)
    pending = w.take_events();
  const std::array<double, 3> state =
      full ? std::array<double, 3>{work, damping, initial_} : w.ledger_state();
  w.restore_progress(step_count(), state, report_, std::move(pending));
  return &w;
}

void RunBody::spread_whole_state() {
  if (!run_)
    return;
  const Lattice& body = lattice();
  std::vector<std::vector<double>> parts;
  double progress[4] = {0.0, 0.0, 0.0, 0.0}; // step, work, damping, initial energy
  if (writes()) {
    const Simulation& w = *c_.sim;
    for (int r = 0; r < ranks_; ++r) {
      const Slab slab = make_slab(body.nz(), ranks_, r);
      std::vector<double> part;
      for (bool previous : {false, true})
        for (const Span& s : slab_node_spans(slab, body, false))
          w.append_displacements(s.global_first, s.count, part, previous);
      for (const Span& s : slab_bar_spans(slab, body, false))
        w.append_histories(s.global_first, s.count, part);
      parts.push_back(std::move(part));
    }
    const std::array<double, 3> ledger = w.ledger_state();
    progress[0] = static_cast<double>(w.step_count());
    progress[1] = ledger[0];
    progress[2] = ledger[1];
    progress[3] = ledger[2];
    report_ = w.last_report();
  }
  const std::vector<double> part = scatter_from_first(parts);
  broadcast_from_first(progress, 4);
  Simulation& sim = run_->sim();
  const double* in = part.data();
  for (bool previous : {false, true})
    for (const Span& s : slab_node_spans(run_->slab(), body, false)) {
      sim.assign_displacements(s.local_first, s.count, in, previous);
      in += 3 * std::size_t{s.count};
    }
  for (const Span& s : slab_bar_spans(run_->slab(), body, false)) {
    sim.assign_histories(s.local_first, s.count, in);
    in += s.count;
  }
  initial_ = progress[3];
  // The body's accumulated work and damping go to the first slab; the others add from zero.
  const std::array<double, 3> ledger =
      writes() ? std::array<double, 3>{progress[1], progress[2], initial_}
               : std::array<double, 3>{0.0, 0.0, initial_};
  sim.restore_progress(static_cast<std::uint64_t>(progress[0]), ledger, {}, {});
}

} // namespace ldem
