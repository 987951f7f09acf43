// `ldem check`, `ldem run`, `ldem resume`, `ldem plot` and `ldem modes`. Run and resume agree
// with the other processes on the case, the body and the output folder, then hand them to the
// run loop (run_loop.hpp).
#include "app/case_run.hpp"
#include "app/run_body.hpp"
#include "app/run_loop.hpp"
#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "parallel/comm.hpp"
#include "solver/modes.hpp"
#include "util/core_share.hpp"
#include "util/error.hpp"
#include "util/text_file.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <omp.h>
#include <sstream>
#include <sys/wait.h>
#include <toml++/toml.h>
#include <variant>

#ifndef LDEM_PLOT_SCRIPT
#define LDEM_PLOT_SCRIPT "tools/plot/ldem_plot.py"
#endif

namespace ldem {

namespace fs = std::filesystem;

int check_command(const std::string& path) {
  const BuiltCase c = build_case(path);
  for (const std::string& w : c.warnings)
    fmt::print(stderr, "ldem: warning: {}\n", w);
  if (const auto w = time_step_warning(body_numbers(*c.sim)))
    fmt::print(stderr, "ldem: warning: {}\n", *w);
  fmt::print("{}", resolved_case_toml(c, body_numbers(*c.sim)));
  fmt::print(stderr, "{}: valid ({} nodes, {} bars, dt = {:.4g} s of a stable {:.4g} s)\n", path,
             c.sim->lattice().num_present_nodes(), c.sim->lattice().num_present_bars(), c.sim->dt(),
             c.sim->stable_step().dt);
  return 0;
}

int modes_command(const std::string& path, int count, int threads) {
  if (count < 1)
    throw InputError(fmt::format("--count: expected a number of modes >= 1, got {}", count));
  if (threads > 0)
    omp_set_num_threads(threads);
  const BuiltCase c = build_case(path);
  for (const std::string& w : c.warnings)
    fmt::print(stderr, "ldem: warning: {}\n", w);
  const Simulation& sim = *c.sim;
  const Lattice& lat = sim.lattice();
  const auto start = std::chrono::steady_clock::now();
  const std::vector<Mode> modes = lowest_modes(sim, count);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  fmt::print("{}: {} x {} x {} modules, {} free DOF of {}, {} pre-cracked bars left out\n", path,
             lat.nx(), lat.ny(), lat.nz(), free_dof_count(sim), 3ull * lat.num_nodes(),
             sim.broken_count());
  const bool loaded = !c.spec.loads.empty();
  fmt::print("lowest modes of K phi = omega^2 M phi (undamaged bars, reference geometry, lumped "
             "masses); participation: share of kinetic energy in x, y, z{}\n\n",
             loaded ? "; load: share of the loads' static work F^T K^-1 F" : "");
  fmt::print("{:>5} {:>15} {:>13} {:>15} {:>7} {:>7} {:>7}{}\n", "mode", "frequency [Hz]",
             "period [s]", "omega [rad/s]", "x [%]", "y [%]", "z [%]",
             loaded ? fmt::format(" {:>9}", "load [%]") : "");
  const Mode* lowest = nullptr;     // the lowest mode that stores energy
  double load_sum = 0.0;            // the load shares of the modes listed
  const Mode* load_first = nullptr; // the lowest mode with at least 1 % of the static work
  for (std::size_t m = 0; m < modes.size(); ++m) {
    const Mode& mode = modes[m];
    std::string pct = fmt::format("{:7.1f} {:7.1f} {:7.1f}", 100 * mode.participation[0],
                                  100 * mode.participation[1], 100 * mode.participation[2]);
    if (loaded)
      pct += std::isnan(mode.load_share) ? fmt::format(" {:>9}", "-")
                                         : fmt::format(" {:9.3g}", 100 * mode.load_share);
    load_sum += mode.load_share;
    if (!load_first && mode.load_share >= 0.01)
      load_first = &mode;
    if (mode.zero_energy) {
      fmt::print("{:5} {:>15} {:>13} {:>15} {}  zero-energy (rigid-body motion or mechanism)\n",
                 m + 1, "0", "-", "0", pct);
      continue;
    }
    if (!lowest)
      lowest = &mode;
    fmt::print("{:5} {:15.6g} {:13.5g} {:15.6g} {}\n", m + 1, mode.frequency_hz,
               1.0 / mode.frequency_hz, mode.omega, pct);
  }
  if (loaded) {
    fmt::print("\n");
    if (std::isnan(load_sum))
      fmt::print("the loads' static response: not available (no load on a free DOF, a free body "
                 "loaded out of equilibrium, or only zero-energy modes listed)\n");
    else if (load_first)
      fmt::print("the loads' static response: {:.4g} % in the {} modes listed; the lowest mode "
                 "with at least 1 % of it: mode {} at {:.6g} Hz\n",
                 100 * load_sum, modes.size(), load_first - modes.data() + 1,
                 load_first->frequency_hz);
    else
      fmt::print("the loads' static response: {:.4g} % in the {} modes listed; none of them has "
                 "1 % of it (ask for more with --count)\n",
                 100 * load_sum, modes.size());
  }
  fmt::print("\n");
  if (!lowest) {
    fmt::print("all {} modes found are zero-energy (the body is free to move); ask for more with "
               "--count\n",
               modes.size());
  } else {
    const double period = 1.0 / lowest->frequency_hz;
    fmt::print("lowest frequency {:.6g} Hz: its period {:.4g} s is {:.0f} time steps of dt = "
               "{:.4g} s\n",
               lowest->frequency_hz, period, period / sim.dt(), sim.dt());
    // Periodic loading: the lowest eigenfrequency against each sine's frequency.
    auto sines = [&](const TimeFunction& f, const std::string& what) {
      for (const TimeTerm& term : f.terms())
        if (const auto* g = std::get_if<GrowingSine>(&term); g && g->frequency > 0.0)
          fmt::print("{}: sine at {:.6g} Hz; lowest frequency / load frequency = {:.3g}\n", what,
                     g->frequency, lowest->frequency_hz / g->frequency);
    };
    for (const LoadSpec& l : c.spec.loads)
      sines(l.scale, fmt::format("load \"{}\"", l.name));
    for (const VelocitySpec& v : c.spec.velocities)
      sines(v.scale, fmt::format("velocity on \"{}\"", v.set));
  }
  std::fflush(stdout);
  fmt::print(stderr, "ldem: {} modes of {} free DOF in {:.2f} s\n", modes.size(),
             free_dof_count(sim), seconds);
  return 0;
}

namespace {

// Checks, after the case has been validated, that `dir` can take a run's outputs: a folder
// that is new or empty (or `force`), and writable; with `create` makes it if it does not exist
// yet. Nothing is created or changed when this throws.
void prepare_output(const std::string& dir, bool force, bool create = true) {
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec))
      throw InputError(fmt::format("--out {}: expected a folder, got a file", dir));
    if (!fs::is_empty(dir, ec) && !force)
      throw InputError(fmt::format("--out {}: the folder is not empty; choose another or pass "
                                   "--force to overwrite its results",
                                   dir));
    const std::string probe = dir + "/.ldem-write-test";
    std::FILE* f = std::fopen(probe.c_str(), "wb");
    if (!f)
      throw InputError(fmt::format("--out {}: the folder is not writable", dir));
    std::fclose(f);
    fs::remove(probe, ec);
    return;
  }
  if (!create)
    return;
  if (!fs::create_directories(dir, ec) || ec)
    throw InputError(fmt::format("--out {}: cannot create the folder ({})", dir,
                                 ec ? ec.message() : "unknown reason"));
}

std::string read_all(const std::string& path) {
  return read_text_file(path, "the case file");
}

// Runs `setup` on every process and agrees on its outcome: when some process threw
// InputError, the lowest such process rethrows it (its message is printed once) and the others
// return false; true when all succeeded.
bool agreed(const std::function<void()>& setup) {
  std::string error;
  try {
    setup();
  } catch (const InputError& e) {
    error = e.what();
  }
  const int rank = process_rank();
  const double first_failed = min_over_processes(error.empty() ? 1e9 : rank);
  if (first_failed >= 1e9)
    return true;
  if (static_cast<int>(first_failed) == rank)
    throw InputError(error);
  return false;
}

// The body of a run: the case's Simulation, or with several processes a subdomain on each (the
// processes agree on whether it could be built).
std::unique_ptr<RunBody> make_body(BuiltCase& c, ProcessGrid asked) {
  if (process_count() == 1)
    return make_serial_body(c);
  std::unique_ptr<RunBody> body;
  if (!agreed([&] {
        const ProcessGrid grid =
            resolve_grid(c.lattice->ny(), c.lattice->nz(), process_count(), asked);
        body = make_distributed_body(c, grid, process_rank());
      }) ||
      !agreed([&] { body->agree_on_body(); }))
    return nullptr;
  return body;
}

} // namespace

int run_command(const std::string& path, const RunOptions& o) {
  catch_stop_signals();
  if (o.threads > 0)
    omp_set_num_threads(o.threads);
  const bool writes = process_rank() == 0;
  BuiltCase c;
  ProcessGrid grid;
  // The first process builds the whole body (its time step, the outputs' copy) and prepares
  // the folder; the others only what their subdomains need.
  if (!agreed([&] {
        c = build_case(path, o.adjust, process_count() == 1,
                       o.case_text ? &*o.case_text : nullptr);
        if (process_count() > 1) // a body too thin to split is refused before any output
          try {
            grid = resolve_grid(c.lattice->ny(), c.lattice->nz(), process_count(),
                                {o.grid_y, o.grid_z});
          } catch (const InputError& e) {
            throw InputError(fmt::format("{}: {}", path, e.what()));
          }
        if (writes) // (made once the body is built: a bad case leaves no folder behind)
          prepare_output(o.out_dir, o.force, false);
      }))
    return 2;
  const std::unique_ptr<RunBody> body = make_body(c, grid);
  if (!body || !agreed([&] {
        if (writes)
          prepare_output(o.out_dir, o.force);
      }))
    return 2;
  const std::string dir = o.out_dir + "/";
  RunState st;
  // The case as one path, however it was typed (./a/../case.toml, a link).
  st.case_path =
      fs::weakly_canonical(fs::absolute(o.case_text ? dir + "case.toml" : path)).string();
  st.plots = o.plots;
  st.checkpoint_every = o.checkpoint_every >= 0 ? static_cast<std::uint64_t>(o.checkpoint_every)
                                                : c.spec.output.checkpoint_every;
  st.checkpoint_seconds =
      o.checkpoint_seconds >= 0 ? o.checkpoint_seconds : c.spec.output.checkpoint_seconds;
  if (writes) {
    for (const std::string& w : c.warnings)
      fmt::print(stderr, "ldem: warning: {}\n", w);
    if (const auto w = time_step_warning(body->numbers()))
      fmt::print(stderr, "ldem: warning: {}\n", *w);
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(o.out_dir)) // --force: old snapshots go
      if (e.path().extension() == ".vtu" && e.path().filename().string().rfind("lattice_", 0) == 0)
        fs::remove(e.path());
    fs::remove_all(o.out_dir + "/checkpoint", ec);
    fs::remove(o.out_dir + "/body.npy", ec); // an earlier shaped body's
    const std::string resolved = resolved_case_toml(c, body->numbers());
    write_file(dir + "case.resolved.toml", resolved);
    if (c.lattice->shaped())
      write_file(dir + "body.npy", module_mask_npy(*c.lattice));
    st.resolved_hash = checkpoint::fnv1a(resolved.data(), resolved.size());
    if (o.case_text)
      write_file(dir + "case.toml", *o.case_text);
    const std::string text = o.case_text ? *o.case_text : read_all(path);
    st.case_hash = checkpoint::fnv1a(text.data(), text.size());
    if (process_count() > 1)
      fmt::print(stderr, "ldem: {}\n", describe_decomposition(*c.lattice, grid));
  }
  return guarded_loop([&] {
    if (body->numbers().per_bar)
      body->write_fields(dir + "fields.csv");
    return run_loop(c, *body, o.out_dir, st, true, st.plots, st.checkpoint_every,
                    st.checkpoint_seconds, shares_cores(o.threads));
  });
}

namespace {

// The tables of a resolved case that a changed case must keep: the body, its material, its
// pre-cracks and its probes (the state, and the columns of the logs, are theirs).
constexpr const char* kKeptTables[] = {"lattice", "geometry", "material", "fields", "region",
                                       "fatigue", "precrack", "probe"};

// Throws InputError naming the first table of kKeptTables that differs between the run's
// resolved case (the file `was`) and the new one (`now`, the text of `path`'s resolution).
void check_same_body(const std::string& was, const std::string& now, const std::string& path) {
  const toml::table a = toml::parse(read_all(was)), b = toml::parse(now);
  for (const char* key : kKeptTables) {
    // Each as a table of that one key, written out.
    toml::table ta, tb;
    if (const toml::node* n = a.get(key))
      ta.insert(key, *n);
    if (const toml::node* n = b.get(key))
      tb.insert(key, *n);
    std::ostringstream x, y;
    x << ta;
    y << tb;
    if (x.str() != y.str())
      throw InputError(fmt::format(
          "{}: [{}] differs from the run's ({}): a resume with a changed case may change its "
          "supports, velocities, loads, node sets, time and analyses, not its body, material, "
          "pre-cracks or probes; nothing was changed",
          path, key, was));
  }
}

} // namespace

int resume_command(const std::string& out_dir, int threads, bool plots, int grid_y, int grid_z,
                   std::optional<double> end, const std::string& new_case) {
  catch_stop_signals();
  if (threads > 0)
    omp_set_num_threads(threads);
  const bool writes = process_rank() == 0;
  const std::string path = out_dir + "/checkpoint/state.ckpt";
  RunState st;
  BuiltCase c;
  // The first process reads the run's state from the checkpoint (written by any number of
  // processes) and checks its case file (unless a changed one is given); every process builds
  // the case (a distributed run its subdomain) and loads its part of the body's state from the
  // file.
  if (!agreed([&] {
        if (!writes)
          return;
        st = parse_run_state(checkpoint::read_header(path).meta);
        if (new_case.empty()) {
          std::string text;
          try {
            text = read_all(st.case_path);
          } catch (const InputError&) {
            throw InputError(fmt::format("{}: the case file of this run is gone; a resume needs "
                                         "it unchanged",
                                         st.case_path));
          }
          if (checkpoint::fnv1a(text.data(), text.size()) != st.case_hash)
            throw InputError(fmt::format(
                "{}: the case file changed since the checkpoint in {}; a resume needs it "
                "unchanged (start a new run instead, or go on with the changed case from the "
                "checkpoint: ldem resume {} --case {})",
                st.case_path, out_dir, out_dir, st.case_path));
        }
        check_folder_matches(out_dir, st); // before anything in the folder changes
      }))
    return 2;
  std::string case_path =
      new_case.empty() ? st.case_path : fs::weakly_canonical(fs::absolute(new_case)).string();
  broadcast_from_first(case_path);
  // The run's options, which every process follows (a checkpoint is written by all of them).
  // (And cycle jumping's progress, which every process follows alike.)
  double options[8] = {st.plots ? 1.0 : 0.0,
                       static_cast<double>(st.checkpoint_every),
                       st.checkpoint_seconds,
                       st.jumped_cycles,
                       st.window_start,
                       st.end_time,
                       static_cast<double>(st.energy_every),
                       static_cast<double>(st.vtu_every)};
  broadcast_from_first(options, 8);
  st.plots = options[0] != 0.0;
  st.checkpoint_every = static_cast<std::uint64_t>(options[1]);
  st.checkpoint_seconds = options[2];
  st.jumped_cycles = options[3];
  st.window_start = options[4];
  st.end_time = options[5];
  st.energy_every = static_cast<std::uint64_t>(options[6]);
  st.vtu_every = static_cast<std::uint64_t>(options[7]);
  if (!agreed([&] { c = build_case(case_path, nullptr, process_count() == 1); }))
    return 2;
  const std::unique_ptr<RunBody> body = make_body(c, {grid_y, grid_z});
  if (!body)
    return 2;
  if (!agreed([&] { body->read_checkpoint(path); }))
    return 2;
  st.next = body->step_count(); // the checkpoint's next step, on every process
  // A changed case goes on to its own end (or --end); the run's intervals stay.
  if (!new_case.empty())
    st.end_time = 0.0;
  const double end_time = end ? *end : st.end_time > 0.0 ? st.end_time : c.spec.end_time;
  if ((end || !new_case.empty()) &&
      (!(end_time > body->time()) || !(end_time / body->dt() <= kMaxSteps))) {
    if (writes)
      fmt::print(stderr,
                 "ldem: {}: {}: expected a time after the checkpoint's, t = {:.9g} s, and at "
                 "most {:g} steps of dt = {:.4g} s, got {:g} s; nothing was changed\n",
                 out_dir, end ? "--end" : case_path + ": time.end", body->time(), kMaxSteps,
                 body->dt(), end_time);
    return 2;
  }
  if (!new_case.empty() && c.spec.material.fatigue && c.spec.material.fatigue->jump) {
    if (writes)
      fmt::print(stderr,
                 "ldem: {}: fatigue.jump: a run that jumps cycles goes on with its own case "
                 "(the jumps follow its loads); nothing was changed\n",
                 case_path);
    return 2;
  }
  if (end)
    st.end_time = *end;
  // A changed case replaces case.resolved.toml (the run's is kept as
  // case.resolved.until_step_<n>.toml), once its body is found the same.
  if (!new_case.empty() && !agreed([&] {
        if (!writes)
          return;
        const std::string resolved = resolved_case_toml(c, body->numbers());
        const std::string was = out_dir + "/case.resolved.toml";
        check_same_body(was, resolved, case_path);
        fs::copy_file(was, fmt::format("{}/case.resolved.until_step_{}.toml", out_dir, st.next),
                      fs::copy_options::overwrite_existing);
        write_file(was, resolved);
        st.resolved_hash = checkpoint::fnv1a(resolved.data(), resolved.size());
        const std::string text = read_all(case_path);
        st.case_hash = checkpoint::fnv1a(text.data(), text.size());
        st.case_path = case_path;
      }))
    return 2;
  if (end || !new_case.empty())
    st.continued.push_back({st.next, end_time, new_case.empty() ? std::string() : case_path});
  st.case_changed = !new_case.empty();
  if (writes)
    fmt::print(stderr, "ldem: resuming {} at step {} (t = {:.4g} s)\n", st.case_path, st.next,
               body->time());
  return guarded_loop([&] {
    // The run's own options; --no-plot here turns its plots off too.
    return run_loop(c, *body, out_dir, st, false, plots && st.plots, st.checkpoint_every,
                    st.checkpoint_seconds, shares_cores(threads));
  });
}

int plot_command(const std::string& dir, const std::string& view, const std::string& cut) {
  // The options go to the script as single-quoted words: refuse a quote in them.
  for (const std::string* o : {&view, &cut})
    if (o->find('\'') != std::string::npos) {
      fmt::print(stderr,
                 "ldem plot: --view/--slice: expected letters, digits, '=' and '.'; got "
                 "'{}'\n",
                 *o);
      return 2;
    }
  // A folder without a resolved case is not an output folder: say so, rather than let the
  // script fail on it.
  const std::string resolved = dir + "/case.resolved.toml";
  if (!std::filesystem::is_regular_file(resolved)) {
    fmt::print(stderr,
               "ldem plot: {}: cannot read the resolved case (expected the output folder of a "
               "run)\n",
               resolved);
    return 2;
  }
  std::string cmd = fmt::format("/usr/bin/python3 '{}'", LDEM_PLOT_SCRIPT);
  if (!view.empty())
    cmd += fmt::format(" --view '{}'", view);
  if (!cut.empty())
    cmd += fmt::format(" --slice '{}'", cut);
  cmd += fmt::format(" '{}'", dir);
  const int rc = std::system(cmd.c_str());
  if (rc != -1 && WIFEXITED(rc) && WEXITSTATUS(rc) == 2)
    return 2; // bad --view or --slice, said by the script
  if (rc != 0) {
    fmt::print(stderr, "ldem: warning: plotting failed ({}); the data files are complete\n",
               plot_failure_reason());
    return 1;
  }
  return 0;
}

std::string plot_failure_reason() {
  if (std::system("/usr/bin/python3 -c 'import matplotlib, numpy' >/dev/null 2>&1") != 0)
    return "needs /usr/bin/python3 with matplotlib and numpy: apt-get install python3-matplotlib";
  return "the plotting script stopped with the message above";
}

} // namespace ldem
