#include "app/run_body.hpp"

#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "parallel/comm.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <numeric>

namespace ldem {

void RunBody::write_fields(const std::string& path) {
  // Every bar up to 2 million, else every stride-th: each with its centre and material.
  const Lattice& whole = lattice();
  const index_t stride = std::max<index_t>(1, whole.num_bars() / 2000000 + 1);
  const std::vector<double> rows = field_rows(stride);
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

std::vector<Event> RunBody::take_kept_events() {
  std::vector<Event> events = std::move(events_);
  events_.clear();
  std::sort(events.begin(), events.end(), event_before);
  return events;
}

double RunBody::load_probe(const ProbeSpec& p, double t) const {
  for (const LoadSpec& l : c_.spec.loads)
    if (l.name == p.load)
      return l.scale(t) *
             std::sqrt(l.force.x * l.force.x + l.force.y * l.force.y + l.force.z * l.force.z) *
             static_cast<double>(set_named(c_.sets, l.set).nodes.size());
  return 0.0;
}

double RunBody::reaction_term(const Simulation& sim, index_t node, int component) {
  const Vec3 f = sim.node_force(node), l = sim.nodal_load(node);
  return component == 0 ? f.x + l.x : component == 1 ? f.y + l.y : f.z + l.z;
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

void RunBody::write_checkpoint(const std::string& path, const std::string& meta) {
  namespace ck = checkpoint;
  const Ledger::State ledger = collect_ledger_and_events();
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

} // namespace ldem
