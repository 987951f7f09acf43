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

void RunBody::control_factors(std::uint64_t step, const std::vector<double>& gauges) {
  // A proportional controller: the set's speed that would cancel the error in response_time
  // if the gauge moved as the set does, at most the set's top speed either way. The target is
  // taken at the step's end, where the velocity of the step brings the gauge.
  const double t_next = static_cast<double>(step + 1) * dt_;
  controls_.resize(c_.controls.size());
  for (std::size_t k = 0; k < c_.controls.size(); ++k) {
    const BuiltCase::Control& ctl = c_.controls[k];
    const double error = ctl.rate * t_next - gauges[k];
    controls_[k] = std::clamp(error / (ctl.response_time * ctl.speed), -1.0, 1.0);
  }
}

double RunBody::load_probe(const ProbeSpec& p, double t) const {
  for (std::size_t i = 0; i < c_.spec.loads.size(); ++i)
    if (c_.spec.loads[i].name == p.load)
      return load_total_force(c_, i, t) * sim().load_factor(i); // (a script's factor)
  return 0.0;
}

double RunBody::reaction_term(const Simulation& sim, index_t node, int component) {
  const Vec3 f = sim.node_force(node), l = sim.nodal_load(node);
  return component == 0 ? f.x + l.x : component == 1 ? f.y + l.y : f.z + l.z;
}

std::size_t RunBody::platen_index(const std::string& name) const {
  const auto& platens = c_.spec.platens;
  return static_cast<std::size_t>(
      std::find_if(platens.begin(), platens.end(),
                   [&](const PlatenSpec& q) { return q.name == name; }) -
      platens.begin());
}

checkpoint::Progress RunBody::body_progress() const {
  checkpoint::Progress p;
  p.step = step_count();
  p.dt = dt_;
  p.nodes = lattice().num_nodes();
  p.bars = lattice().num_bars();
  p.law = std::string(sim().law_name());
  p.arrays = sim().state_arrays();
  p.platens = sim().platen_positions();
  return p;
}

template <class F> void RunBody::for_each_owned_piece(const checkpoint::Progress& p, F&& visit) {
  // Each array of the state in turn, a piece per span of the nodes or bars this process owns.
  std::vector<double>& buf = send_;
  for (std::size_t a = 0; a < p.arrays.size(); ++a)
    for (const Span& s : p.arrays[a].per_bar ? bar_spans(true) : node_spans(true)) {
      buf.clear();
      sim().append_state(a, s.local_first, s.count, buf);
      visit(p.array_place(a) + s.global_first, buf.data(), s.count);
    }
}

void RunBody::write_checkpoint(const std::string& path, const std::string& meta) {
  namespace ck = checkpoint;
  ck::Progress p = body_progress();
  p.ledger = collect_ledger_and_events();
  std::sort(events_.begin(), events_.end(), event_before); // (kept: written at the next report)
  std::string progress;
  std::uint64_t sum = 0;
  if (writes()) {
    p.report = report_;
    p.events = events_;
    progress = ck::progress_bytes(p);
    sum = ck::fnv1a(meta.data(), meta.size()) + ck::fnv1a(progress.data(), progress.size());
  }
  double sizes[2] = {static_cast<double>(meta.size()), static_cast<double>(progress.size())};
  broadcast_from_first(sizes, 2);
  const std::uint64_t at = ck::Header::arrays_offset(static_cast<std::uint64_t>(sizes[0]),
                                                     static_cast<std::uint64_t>(sizes[1]));
  SharedFile file(path);
  for_each_owned_piece(p, [&](std::uint64_t place, const double* v, index_t count) {
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
  ck::Progress p = ck::read_progress(h, path);
  ck::check_resumes(p, h, body_progress(), path);
  // The window's nodes and bars (owned and ghosts), each array's values from their places.
  std::ifstream in(path, std::ios::binary);
  std::vector<double>& buf = send_;
  const std::uint64_t at = h.arrays_at();
  Simulation& s = sim();
  for (std::size_t a = 0; a < p.arrays.size(); ++a)
    for (const Span& sp : p.arrays[a].per_bar ? bar_spans(false) : node_spans(false)) {
      buf.resize(sp.count);
      in.seekg(static_cast<std::streamoff>(at + 8 * (p.array_place(a) + sp.global_first)));
      if (!in.read(reinterpret_cast<char*>(buf.data()),
                   static_cast<std::streamsize>(8 * std::size_t{sp.count})))
        throw InputError(fmt::format("{}: cannot read the checkpoint", path));
      s.assign_state(a, sp.local_first, sp.count, buf.data());
    }
  // The checksum: every process adds the terms of what it owns.
  std::uint64_t sum = writes() ? ck::fnv1a(h.meta.data(), h.meta.size()) +
                                     ck::fnv1a(h.progress.data(), h.progress.size())
                               : 0;
  for_each_owned_piece(p, [&](std::uint64_t place, const double* v, index_t count) {
    for (index_t i = 0; i < count; ++i)
      sum += ck::word_hash(place + i, v[i]);
  });
  if (wrapping_sum_over_processes(sum) != h.checksum)
    throw InputError(fmt::format("{}: checkpoint checksum mismatch: the file is corrupt", path));
  initial_ = p.ledger.initial;
  // The body's accumulated work and damping go to the first process; the others add from zero.
  if (!writes())
    p.ledger = Ledger::State{{}, {}, {}, initial_};
  s.restore_progress(p.step, p.ledger, p.report, {});
  s.set_platen_positions(p.platens);
  report_ = p.report;
  events_ = writes() ? std::move(p.events) : std::vector<Event>{};
  return h.meta;
}

namespace {
// The index of the law's state array `name`; throws std::logic_error for a law without it.
std::size_t state_array(const Simulation& s, std::string_view name) {
  const auto arrays = s.bar_state_arrays();
  for (std::size_t a = 0; a < arrays.size(); ++a)
    if (arrays[a].name == name)
      return a;
  throw std::logic_error(fmt::format("the bar law {} has no state array {}", s.law_name(), name));
}
} // namespace

void RunBody::mark_lives() {
  Simulation& s = sim();
  const std::span<double> life = s.bar_state_array(state_array(s, "life"));
  const std::span<double> mark = s.bar_state_array(state_array(s, "life_at_window"));
  std::copy(life.begin(), life.end(), mark.begin());
}

double RunBody::jump_cycles(std::uint64_t breaks, double window, double cap, double fraction) {
  Simulation& s = sim();
  const std::span<double> life = s.bar_state_array(state_array(s, "life"));
  const std::span<double> mark = s.bar_state_array(state_array(s, "life_at_window"));
  // Each owned bar's cycles to the end of its life at its rate (the breaks + 1 fewest), and
  // the fewest cycles in which a bar uses a whole life (1) at its rate.
  std::vector<double> left;
  double fastest = INFINITY;
  for (const Span& sp : bar_spans(true))
    for (index_t b = sp.local_first; b < sp.local_first + sp.count; ++b) {
      const double per_cycle = (mark[b] - life[b]) / window;
      if (per_cycle > 0.0 && life[b] > 0.0 && s.bar_state(b) != BarState::Broken) {
        left.push_back(life[b] / per_cycle);
        fastest = std::min(fastest, 1.0 / per_cycle);
      }
    }
  const auto keep = static_cast<std::ptrdiff_t>(
      std::min<std::uint64_t>(breaks + 1, static_cast<std::uint64_t>(left.size())));
  std::partial_sort(left.begin(), left.begin() + keep, left.end());
  left.resize(static_cast<std::size_t>(keep));
  // Per process: fastest, the count of its cycles left, those.
  std::vector<double> mine{fastest, static_cast<double>(keep)};
  mine.insert(mine.end(), left.begin(), left.end());
  const std::vector<double> all = gather_on_first(mine);
  double cycles = 0.0;
  if (rank_ == 0) {
    std::vector<double> fewest;
    double fastest_all = INFINITY;
    for (std::size_t p = 0; p < all.size();) {
      const auto count = static_cast<std::size_t>(all[p + 1]);
      fastest_all = std::min(fastest_all, all[p]);
      fewest.insert(fewest.end(), all.begin() + static_cast<std::ptrdiff_t>(p + 2),
                    all.begin() + static_cast<std::ptrdiff_t>(p + 2 + count));
      p += 2 + count;
    }
    std::sort(fewest.begin(), fewest.end());
    // A bar with r cycles left reaches its end within a jump of n >= r cycles: the jump stays
    // below the (breaks + 1)-th fewest; and no bar uses more than `fraction` of a life in it.
    cycles = fewest.size() > breaks ? std::ceil(fewest[breaks]) - 1.0 : cap;
    if (std::isfinite(fastest_all))
      cycles = std::min(cycles, std::floor(fraction * fastest_all));
    cycles = std::clamp(cycles, 0.0, std::floor(cap));
  }
  broadcast_from_first(&cycles, 1);
  return cycles;
}

void RunBody::jump_lives(double cycles, double window) {
  Simulation& s = sim();
  const std::span<double> life = s.bar_state_array(state_array(s, "life"));
  const std::span<double> mark = s.bar_state_array(state_array(s, "life_at_window"));
  for (std::size_t b = 0; b < life.size(); ++b) {
    const double per_cycle = (mark[b] - life[b]) / window;
    if (per_cycle > 0.0 && life[b] > 0.0)
      life[b] -= per_cycle * cycles;
    mark[b] = life[b];
  }
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
