// The time-step loop of `ldem run` and `ldem resume`: the outputs, checkpoints, stop signals
// and the end of a run.
#include "app/run_loop.hpp"

#include "analysis/crack.hpp"
#include "analysis/fatigue.hpp"
#include "app/run_body.hpp"
#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "parallel/comm.hpp"
#include "util/core_share.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fmt/format.h>
#include <omp.h>
#include <optional>
#include <unistd.h>

namespace ldem {

namespace fs = std::filesystem;

namespace {

// The signal that asked the run to stop (SIGINT or SIGTERM), 0 while none has.
std::atomic<int> g_interrupted{0};
void on_signal(int sig) {
  g_interrupted = sig;
}

class Progress {
public:
  Progress(std::uint64_t total) : total_(total), tty_(isatty(fileno(stderr))) {
    start_ = last_ = std::chrono::steady_clock::now();
  }
  void update(std::uint64_t step, double t, std::uint64_t broken, double balance, bool last) {
    const auto now = std::chrono::steady_clock::now();
    const double since = std::chrono::duration<double>(now - last_).count();
    const double frac =
        static_cast<double>(step) / static_cast<double>(std::max<std::uint64_t>(total_, 1));
    if (!last && since < (tty_ ? 0.2 : 10.0))
      return;
    last_ = now;
    const double el = std::chrono::duration<double>(now - start_).count();
    const double eta = frac > 0 ? el * (1 - frac) / frac : 0;
    const int w = 30, fill = static_cast<int>(frac * w);
    const std::string line = fmt::format(
        "step {}/{}  t = {:.4g} s  broken {}  balance {:.1e}  elapsed {:.0f} s  ETA {:.0f} s", step,
        total_, t, broken, balance, el, eta);
    if (tty_)
      fmt::print(stderr, "\r[{}{}] {:3.0f}%  {}\x1b[K{}", std::string(fill, '#'),
                 std::string(w - fill, '.'), 100 * frac, line, last ? "\n" : "");
    else
      fmt::print(stderr, "ldem: {:3.0f}%  {}\n", 100 * frac, line);
  }

private:
  std::uint64_t total_;
  bool tty_;
  std::chrono::steady_clock::time_point start_, last_;
};

} // namespace

std::string run_state_bytes(const RunState& st) {
  using checkpoint::put;
  std::string meta;
  checkpoint::put_str(meta, st.case_path);
  put(meta, st.case_hash);
  put(meta, st.next);
  put(meta, static_cast<std::uint64_t>(st.snapshots.size()));
  for (const auto& [t, name] : st.snapshots) {
    put(meta, t);
    checkpoint::put_str(meta, name);
  }
  put(meta, st.n_soft);
  put(meta, st.n_broken);
  put(meta, st.max_balance);
  for (std::uint64_t l : st.lengths)
    put(meta, l);
  put(meta, st.resolved_hash);
  for (std::uint64_t h : st.log_hashes)
    put(meta, h);
  for (std::uint64_t b : st.snapshot_bytes)
    put(meta, b);
  put(meta, static_cast<std::uint8_t>(st.plots));
  put(meta, st.checkpoint_every);
  put(meta, st.checkpoint_seconds);
  put(meta, st.jumped_cycles);
  put(meta, st.window_start);
  put(meta, st.end_time);
  put(meta, st.energy_every);
  put(meta, st.vtu_every);
  put(meta, static_cast<std::uint64_t>(st.continued.size()));
  for (const RunState::Continuation& k : st.continued) {
    put(meta, k.step);
    put(meta, k.end_time);
    checkpoint::put_str(meta, k.case_path);
  }
  return meta;
}

RunState parse_run_state(const std::string& meta) {
  using checkpoint::get;
  std::size_t pos = 0;
  RunState st;
  st.case_path = checkpoint::get_str(meta, pos);
  get(meta, pos, st.case_hash);
  get(meta, pos, st.next);
  std::uint64_t ns = 0;
  get(meta, pos, ns);
  for (std::uint64_t i = 0; i < ns; ++i) {
    double t = 0;
    get(meta, pos, t);
    st.snapshots.emplace_back(t, checkpoint::get_str(meta, pos));
  }
  get(meta, pos, st.n_soft);
  get(meta, pos, st.n_broken);
  get(meta, pos, st.max_balance);
  for (std::uint64_t& l : st.lengths)
    get(meta, pos, l);
  get(meta, pos, st.resolved_hash);
  for (std::uint64_t& h : st.log_hashes)
    get(meta, pos, h);
  st.snapshot_bytes.resize(st.snapshots.size());
  for (std::uint64_t& b : st.snapshot_bytes)
    get(meta, pos, b);
  std::uint8_t plots = 1;
  get(meta, pos, plots);
  st.plots = plots != 0;
  get(meta, pos, st.checkpoint_every);
  get(meta, pos, st.checkpoint_seconds);
  get(meta, pos, st.jumped_cycles);
  get(meta, pos, st.window_start);
  get(meta, pos, st.end_time);
  get(meta, pos, st.energy_every);
  get(meta, pos, st.vtu_every);
  std::uint64_t nc = 0;
  get(meta, pos, nc);
  for (std::uint64_t i = 0; i < nc; ++i) {
    RunState::Continuation k;
    get(meta, pos, k.step);
    get(meta, pos, k.end_time);
    k.case_path = checkpoint::get_str(meta, pos);
    st.continued.push_back(std::move(k));
  }
  return st;
}

void check_folder_matches(const std::string& out_dir, const RunState& st) {
  const std::string dir = out_dir + "/";
  const std::string resolved = dir + "case.resolved.toml";
  const std::optional<std::uint64_t> rh =
      prefix_hash(resolved, fs::exists(resolved) ? fs::file_size(resolved) : 0);
  if (!fs::exists(resolved) || rh != st.resolved_hash)
    throw InputError(fmt::format(
        "{}: {} since the checkpoint was written (or the checkpoint is another run's); a resume "
        "needs the folder as its run left it",
        resolved, fs::exists(resolved) ? "changed" : "missing"));
  for (std::size_t i = 0; i < 3; ++i) {
    const std::string log = log_in_progress(dir + kLogs[i]);
    if (prefix_hash(log, st.lengths[i]) != st.log_hashes[i])
      throw InputError(fmt::format(
          "{}: does not begin with the {} bytes the checkpoint in {}checkpoint counted (the "
          "checkpoint is another run's or a later one, or the file was changed); nothing was "
          "changed",
          log, st.lengths[i], dir));
  }
  for (std::size_t k = 0; k < st.snapshots.size(); ++k) {
    const std::string snap = dir + st.snapshots[k].second;
    std::error_code ec;
    const std::uint64_t bytes = fs::file_size(snap, ec);
    if (ec || bytes != st.snapshot_bytes[k])
      throw InputError(fmt::format("{}: {} (the checkpoint recorded {} bytes); a resume needs "
                                   "every snapshot the run wrote; nothing was changed",
                                   snap, ec ? "missing" : fmt::format("{} bytes", bytes),
                                   st.snapshot_bytes[k]));
  }
}

std::uint64_t run_steps(double end_time, double dt) {
  return static_cast<std::uint64_t>(std::ceil(end_time / dt - 1e-9));
}

namespace {
// summary.json's record of the resumes that changed the run (`ldem resume --end`, `--case`):
// where each began, the end it ran to and, if it changed the case, the case it went on with;
// nothing for a run never continued so.
std::string continued_json(const RunState& st, double dt) {
  if (st.continued.empty())
    return {};
  std::string list;
  for (const RunState::Continuation& k : st.continued)
    list += fmt::format("{}{{\"step\": {}, \"time\": {:.9g}, \"end_time\": {:.9g}{}}}",
                        list.empty() ? "" : ", ", k.step, static_cast<double>(k.step) * dt,
                        k.end_time,
                        k.case_path.empty() ? std::string()
                                            : fmt::format(", \"case\": \"{}\"", k.case_path));
  return fmt::format("  \"continued\": [{}],\n", list);
}

bool energies_finite(const EnergyReport& r) {
  return std::isfinite(r.external_work) && std::isfinite(r.elastic) && std::isfinite(r.kinetic) &&
         std::isfinite(r.damage_dissipated) && std::isfinite(r.damping_dissipated) &&
         std::isfinite(r.fatigue_dissipated) && std::isfinite(r.contact) &&
         std::isfinite(r.friction_dissipated) && std::isfinite(r.balance_error);
}
} // namespace

int run_loop(BuiltCase& c, RunBody& body, const std::string& out_dir, RunState st, bool fresh,
             bool plots, std::uint64_t checkpoint_every, double checkpoint_seconds,
             bool share_cores) {
  const CaseSpec& s = c.spec;
  const Lattice& lat = body.lattice();
  const bool writes = body.writes();
  const std::string dir = out_dir + "/";
  auto steps = run_steps(st.end_time > 0.0 ? st.end_time : s.end_time, body.dt());
  // (Fixed at the run's start: a continued run keeps them.)
  if (!st.energy_every)
    st.energy_every =
        s.output.energy_every ? s.output.energy_every : std::max<std::uint64_t>(1, steps / 500);
  if (!st.vtu_every)
    st.vtu_every = s.output.vtu_every ? s.output.vtu_every : std::max<std::uint64_t>(1, steps / 20);
  const std::uint64_t every = st.energy_every, vtu_every = st.vtu_every;

  auto open = [&](const char* name, int i) -> std::unique_ptr<OutputFile> {
    if (!writes)
      return nullptr;
    return fresh ? std::make_unique<OutputFile>(dir + name, OutputFile::Kind::Log)
                 : std::make_unique<OutputFile>(dir + name, st.lengths[i]);
  };
  const auto energy = open(kLogs[0], 0), events = open(kLogs[1], 1), probes = open(kLogs[2], 2);
  // A law with a fatigue life adds the energy its broken bars held (a column before the error).
  const bool fatigue_column = body.counts_cycles();
  // Platens add the energy their springs hold and what their friction dissipated (after it).
  const bool platen_columns = !s.platens.empty();
  // Cycle jumping adds the cycles jumped before each row's state (after the error).
  const std::optional<FatigueSpec>& fatigue = s.material.fatigue;
  const bool jumping = fatigue && fatigue->jump && c.cycle.has_value();
  if (fresh && writes) {
    energy->write(fmt::format("time,external_work,elastic,kinetic,damage_dissipated,"
                              "damping_dissipated,{}{}balance_error{}\n",
                              fatigue_column ? "fatigue_dissipated," : "",
                              platen_columns ? "contact_energy,friction_dissipated," : "",
                              jumping ? ",jumped_cycles" : ""));
    events->write("bar,event,time,x,y,z\n");
    std::string head = "time";
    for (const ProbeSpec& p : s.probes)
      head += "," + p.name;
    probes->write(head + "\n");
  }
  auto flush_events = [&] { // first process
    std::string rows;
    for (const Event& e : body.take_events()) {
      const Vec3 m = lat.bar_centre(e.bar);
      (e.state == BarState::Softening ? st.n_soft : st.n_broken)++;
      rows += fmt::format("{},{},{:.9g},{:.9g},{:.9g},{:.9g}\n", e.bar,
                          e.state == BarState::Softening ? "softening" : "broken",
                          static_cast<double>(e.step) * body.dt(), m.x, m.y, m.z);
    }
    events->write(rows);
  };
  // The probes at the start of the last report step.
  auto probe_row = [&]() {
    std::string row = fmt::format("{:.9g}", body.last_report().time);
    for (double v : body.last_probes())
      row += fmt::format(",{:.9g}", v);
    probes->write(row + "\n");
  };
  // The rows written so far and the list of snapshots reach the files at most once a second
  // (flush_live), at every checkpoint and at the end: a crash loses nothing that `ldem resume`
  // does not write again from the last checkpoint, and a run's files can be watched as it goes.
  // (A flush per report, and lattice.pvd renamed over itself after each snapshot, which makes
  // the file system write it out at once, cost a tenth of a short run.)
  bool pvd_pending = false;
  auto last_flush = std::chrono::steady_clock::now();
  auto flush_live = [&]() {
    energy->flush();
    events->flush();
    probes->flush();
    if (pvd_pending)
      write_file(dir + "lattice.pvd", lattice_pvd(st.snapshots));
    pvd_pending = false;
    last_flush = std::chrono::steady_clock::now();
  };
  auto save_checkpoint = [&](std::uint64_t next) {
    std::string meta;
    if (writes) {
      flush_live();
      st.next = next;
      st.lengths[0] = energy->size();
      st.lengths[1] = events->size();
      st.lengths[2] = probes->size();
      st.log_hashes[0] = energy->hash();
      st.log_hashes[1] = events->hash();
      st.log_hashes[2] = probes->hash();
      st.snapshot_bytes.clear();
      for (const auto& snap : st.snapshots)
        st.snapshot_bytes.push_back(fs::file_size(dir + snap.second));
      meta = run_state_bytes(st);
      fs::create_directories(dir + "checkpoint");
    }
    if (body.distributed())
      barrier(); // the folder exists before the processes open the file
    body.write_checkpoint(dir + "checkpoint/state.ckpt", meta);
  };

  // The snapshot writer prepares what does not change during the run (connectivity, fields)
  // here, with the rest of the set-up, so that the loop's timing holds only per-step work.
  if (s.output.vtu)
    body.prepare_snapshots();
  std::unique_ptr<Progress> progress;
  if (writes)
    progress = std::make_unique<Progress>(steps);
  // The run's share of the cores, now and about once a second (a thread count changes no
  // result: each process chooses its own).
  auto last_share = std::chrono::steady_clock::now();
  const auto share = [&](std::uint64_t step) {
    const int before = body.threads();
    const int now = body.set_threads(current_core_share());
    omp_set_num_threads(now);
    last_share = std::chrono::steady_clock::now();
    if (writes && now != before) {
      const std::size_t runs = stepping_runs().size();
      fmt::print(stderr, "{}ldem: {} on this machine's {} cores: {} thread{} from step {}\n",
                 isatty(fileno(stderr)) && step > st.next ? "\n" : "",
                 runs > 1 ? fmt::format("{} runs", runs) : "alone", omp_get_num_procs(), now,
                 now > 1 ? "s" : "", step);
    }
  };
  if (share_cores)
    share(st.next);
  const auto t0 = std::chrono::steady_clock::now();
  auto last_checkpoint = t0;
  const std::uint64_t first = st.next;
  std::uint64_t n = st.next;
  std::string blow_up, stopped_by;
  bool blew_up = false;
  // A blow-up: displacements beyond any physical scale, or energies that are no longer numbers.
  const double blow_up_limit =
      1e3 * lat.L() * static_cast<double>(std::max({lat.nx(), lat.ny(), lat.nz()}));
  auto blow_up_message = [&](std::uint64_t step, index_t bad, const std::string& energies) {
    // (Every process takes part in finding the node and its displacement.)
    const Vec3 u = bad < lat.num_nodes() ? body.displacement(bad) : Vec3{};
    if (!writes)
      return std::string();
    std::string where;
    if (bad < lat.num_nodes()) {
      const Vec3 x = lat.position(bad);
      where = fmt::format("node {} at ({:g}, {:g}, {:g}) m has displacement ({:g}, {:g}, {:g}) m",
                          bad, x.x, x.y, x.z, u.x, u.y, u.z);
    }
    return fmt::format("numerical blow-up detected at step {} (t = {:.6g} s): {}{}{}. Check the "
                       "case's loads, velocities, damping and material values; the outputs are "
                       "complete up to the last report before this step",
                       step, body.time(), where, !where.empty() && !energies.empty() ? "; " : "",
                       energies);
  };
  int signal = 0;
  // One process looks at signals and the clock every step; processes of a distributed run
  // agree on them every 10 steps (one reduction each), so that all stop at the same step.
  const std::uint64_t agree_every = body.distributed() ? 10 : 1;
  for (; n <= steps; ++n) {
    // An interruption stops between steps: the checkpoint holds the state before step n and
    // the outputs hold every row of the steps before it, so a resumed run writes exactly
    // what the uninterrupted one would have.
    const bool look = n % agree_every == 0;
    if (look && (signal = body.max_over_processes(g_interrupted)) != 0)
      break;
    bool save = n > first && checkpoint_every && n % checkpoint_every == 0;
    // The end: the state whose report is the run's last row, before the step that reports it
    // (output.end_checkpoint), from which a resume with a later end goes on.
    save |= n == steps && n > first && s.output.end_checkpoint;
    // A changed case: its checkpoint at once (the folder's case.resolved.toml is the new one).
    save |= n == first && st.case_changed;
    if (look && n > first && checkpoint_seconds > 0) // the first process's clock decides
      save |=
          body.max_over_processes(writes && std::chrono::duration<double>(
                                                std::chrono::steady_clock::now() - last_checkpoint)
                                                    .count() > checkpoint_seconds) != 0;
    if (save) {
      save_checkpoint(n);
      last_checkpoint = std::chrono::steady_clock::now();
    }
    if (share_cores && n % 10 == 0 &&
        std::chrono::steady_clock::now() - last_share > std::chrono::seconds(1))
      share(n);
    // Every 10 steps, a look for a numerical blow-up (a NaN, or displacements beyond any
    // physical scale): the run stops with the first bad node, keeping its outputs up to here
    // and its last checkpoint.
    if (n % 10 == 0) {
      const index_t bad = body.first_node_beyond(blow_up_limit);
      if (bad < lat.num_nodes()) {
        blew_up = true;
        blow_up = blow_up_message(n, bad, "");
        break;
      }
      if (s.stop_displacement > 0) {
        const index_t far = body.first_node_beyond(s.stop_displacement);
        if (far < lat.num_nodes()) {
          const Vec3 x = lat.position(far);
          stopped_by = fmt::format("node {} at ({:g}, {:g}, {:g}) m moved beyond "
                                   "time.stop_displacement = {:g} m at t = {:.6g} s",
                                   far, x.x, x.y, x.z, s.stop_displacement, body.time());
          steps = n; // this step is the last: it is reported and written as the run's end
        }
      }
    }
    const bool report = n % every == 0 || n == steps;
    if (s.output.vtu && (n % vtu_every == 0 || n == steps)) {
      // (The first process keeps the list of snapshots: it names the file.)
      std::string name = fmt::format("lattice_{:06d}.vtu", st.snapshots.size());
      if (body.distributed())
        broadcast_from_first(name);
      body.write_snapshot(dir + name);
      if (writes) {
        st.snapshots.emplace_back(body.time(), name);
        pvd_pending = true;
      }
    }
    body.step(report);
    // Energies that are no longer numbers (an overflow the displacement scan has not yet
    // seen): the run stops as for a blow-up, without the row, instead of reporting them.
    if (report && body.max_over_processes(writes && !energies_finite(body.last_report())) != 0) {
      blew_up = true;
      const EnergyReport& r = body.last_report();
      blow_up = blow_up_message(
          n, body.first_node_beyond(blow_up_limit),
          writes ? fmt::format("the energies are no longer finite (external work {:g}, elastic "
                               "{:g}, kinetic {:g}, dissipated {:g} and {:g} J)",
                               r.external_work, r.elastic, r.kinetic, r.damage_dissipated,
                               r.damping_dissipated)
                 : std::string());
      break;
    }
    if (report && writes) {
      probe_row();
      flush_events();
      const EnergyReport& r = body.last_report();
      energy->write(fmt::format(
          "{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{}{}{:.6g}{}\n", r.time, r.external_work,
          r.elastic, r.kinetic, r.damage_dissipated, r.damping_dissipated,
          fatigue_column ? fmt::format("{:.9g},", r.fatigue_dissipated) : std::string(),
          platen_columns ? fmt::format("{:.9g},{:.9g},", r.contact, r.friction_dissipated)
                         : std::string(),
          r.balance_error, jumping ? fmt::format(",{:.17g}", st.jumped_cycles) : std::string()));
      if (r.external_work + r.initial > 1e-6 * (r.elastic + r.kinetic + r.damage_dissipated +
                                                r.fatigue_dissipated + r.contact) &&
          n > 0)
        st.max_balance = std::max(st.max_balance, r.balance_error);
      if (std::chrono::steady_clock::now() - last_flush > std::chrono::seconds(1))
        flush_live();
      progress->update(n, r.time, st.n_broken, r.balance_error, n == steps);
    }
    // Cycle jumping, at report steps once the load's amplitude is constant, on every process
    // alike: a window of resolved cycles is marked; at the first report past its end, the
    // lives move on by as many whole cycles as the rule allows, at the rate each bar used its
    // life over the window's whole cycles, and a new window starts. The first window after
    // the amplitude became constant only settles (its start still has the growth's
    // transient).
    if (jumping && report) {
      const double t_row = static_cast<double>(n) * body.dt();
      const double f = c.cycle->frequency;
      const auto window = static_cast<double>(fatigue->jump_window);
      if (t_row >= c.cycle->t_constant && st.window_start < 0.0) {
        body.mark_lives();
        st.window_start = t_row;
      } else if (st.window_start >= 0.0 && (t_row - st.window_start) * f >= window) {
        const double resolved = std::round((t_row - st.window_start) * f);
        const bool settled = st.window_start >= c.cycle->t_constant + (window - 0.5) / f;
        const double jump = settled ? body.jump_cycles(fatigue->jump_breaks, resolved,
                                                       fatigue->jump_max, fatigue->jump_fraction)
                                    : 0.0;
        body.jump_lives(jump, resolved);
        st.jumped_cycles += jump;
        st.window_start = t_row;
      }
    }
  }
  if (signal)
    save_checkpoint(n);
  if (writes)
    flush_live(); // the last rows and snapshots, within the loop's time
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The final state. Broken bars are those broken during the run (their rupture is in
  // events.csv, as crack.png counts them); the pre-cracked ones, broken from the start, are
  // counted apart.
  const auto [softened, broken] = body.softening_and_broken();
  if (!writes) // the first process reports; the others end with its exit code
    return blew_up ? 3 : signal == SIGTERM ? 143 : signal ? 130 : 0;
  energy->commit();
  events->commit();
  probes->commit();
  // What the run simulated: up to the time of its last reported state. A run that reaches its
  // end (time.end, or time.stop_displacement) takes one step more, from that state, whose start
  // is the report (a step's energies are those at its start); an interrupted or blown-up run
  // stops before step n. The rate counts every step taken.
  const std::uint64_t simulated = signal || blew_up ? n : n - 1;
  const std::uint64_t done = n - first;
  const ProcessGrid grid = body.grid();
  write_file(
      dir + "summary.json",
      fmt::format(
          "{{\n  \"case\": \"{}\",\n  \"title\": \"{}\",\n  \"nodes\": {},\n"
          "  \"bars\": {},\n  \"steps\": {},\n  \"dt\": {:.9g},\n"
          "  \"dt_stable\": {:.9g},\n  \"end_time\": {:.9g},\n  \"wall_s\": {:.4f},\n"
          "  \"bar_updates_per_s\": {:.6g},\n  \"threads\": {},\n  \"processes\": {},\n"
          "  \"process_grid\": [1, {}, {}],\n  \"bytes_per_module\": {:.1f},\n"
          "  \"max_balance_error\": {:.6g},\n  \"softening_bars_at_end\": {},\n"
          "  \"broken_bars_at_end\": {},\n  \"precracked_bars\": {},\n"
          "  \"interrupted\": {},\n  \"stopped_by\": {},\n{}{}  \"analysis\": {{}}\n}}\n",
          st.case_path, s.title, lat.num_present_nodes(), lat.num_present_bars(), simulated,
          body.dt(), body.stable_step().dt, static_cast<double>(simulated) * body.dt(), wall,
          static_cast<double>(lat.num_present_bars()) * static_cast<double>(done) / wall,
          omp_get_max_threads(), process_count(), grid.py, grid.pz, body.numbers().bytes_per_module,
          st.max_balance, softened, broken - c.precracked.size(), c.precracked.size(),
          signal ? "true" : "false",
          stopped_by.empty() ? std::string("null") : "\"" + stopped_by + "\"",
          jumping ? fmt::format("  \"jumped_cycles\": {:.17g},\n"
                                "  \"cycles_at_constant_amplitude\": {:.17g},\n",
                                st.jumped_cycles,
                                st.jumped_cycles +
                                    c.cycle->frequency *
                                        std::max(0.0, static_cast<double>(simulated) * body.dt() -
                                                          c.cycle->t_constant))
                  : std::string(),
          continued_json(st, body.dt())));
  if (!blow_up.empty()) {
    fmt::print(stderr, "ldem: error: {}\n", blow_up);
    return 3;
  }
  if (signal) {
    fmt::print(stderr,
               "ldem: stopped by {} at t = {:.4g} s (step {}); outputs complete up to then and "
               "a checkpoint in {}/checkpoint. Continue with: ldem resume {}{}\n",
               signal == SIGTERM ? "SIGTERM" : "SIGINT", body.time(), n, out_dir, out_dir,
               body.distributed() ? " (or under mpirun, with any number of processes)" : "");
    return signal == SIGTERM ? 143 : 130;
  }
  if (!stopped_by.empty())
    fmt::print(stderr, "ldem: the run ended before time.end: {}\n", stopped_by);
  if (s.analysis.crack)
    analyze_crack_dir(out_dir);
  if (s.analysis.fatigue)
    fmt::print(stderr, "ldem: fatigue: {}\n", fatigue_report(analyze_fatigue_dir(out_dir)));
  if (plots && s.output.plots)
    plot_command(out_dir);
  fmt::print(stderr, "ldem: done: {} steps to t = {:.4g} s in {:.1f} s, results in {}\n", simulated,
             static_cast<double>(simulated) * body.dt(), wall, out_dir);
  return 0;
}

void catch_stop_signals() {
  g_interrupted = 0;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

int guarded_loop(const std::function<int()>& loop) {
  if (process_count() == 1)
    return loop();
  try {
    return loop();
  } catch (const std::exception& e) {
    fmt::print(stderr, "ldem: error: {} (process {} of {}; ending all of them)\n", e.what(),
               process_rank(), process_count());
    abort_processes(dynamic_cast<const InputError*>(&e) ? 2 : 1);
    throw;
  }
}

} // namespace ldem
