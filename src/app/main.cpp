// The ldem command line.
#include "analysis/crack.hpp"
#include "analysis/fatigue.hpp"
#include "app/bench.hpp"
#include "app/case_run.hpp"
#include "app/ensemble.hpp"
#include "io/case_spec.hpp"
#include "parallel/comm.hpp"
#include "util/error.hpp"

#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fmt/format.h>
#include <iostream>
#include <omp.h>

namespace {
constexpr const char* kVersion = "0.1.0";

// A whole number from lo to hi; the message says so in words (`note`: what the range means).
CLI::Validator whole_in(long long lo, long long hi, const std::string& note = "") {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        long long v = 0;
        const char* end = text.data() + text.size();
        const auto [p, ec] = std::from_chars(text.data(), end, v);
        if (ec == std::errc() && p == end && v >= lo && v <= hi)
          return "";
        return fmt::format("expected a whole number from {} to {}{}; got '{}'", lo, hi, note, text);
      },
      fmt::format("{} to {}", lo, hi));
}

// A finite number of at least lo (not nan, not inf).
CLI::Validator finite_at_least(double lo) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (!text.empty() && end == text.c_str() + text.size() && std::isfinite(v) && v >= lo)
          return "";
        return fmt::format("expected a finite number of at least {}; got '{}'", lo, text);
      },
      fmt::format(">= {}", lo));
}

// A folder name that is not empty.
const CLI::Validator kNonEmpty(
    [](std::string& text) -> std::string {
      return text.empty() ? "expected a folder; got an empty name" : "";
    },
    "FOLDER");
} // namespace

int main(int argc, char** argv) {
  const ldem::ProcessGroup processes(argc, argv);
  // Thread counts up to four times the processors this machine has: more only share them, cost
  // memory and time, and a typing error (100000) would take the machine down; a few more than
  // the processors stay allowed (a check of thread-count independence on a small machine).
  const int cores = omp_get_num_procs();
  const CLI::Validator threads_check = whole_in(
      0, 4 * cores, fmt::format(" (0: all; at most 4 times this machine's {} processors)", cores));
  CLI::App app{"ldem: crack propagation in quasi-brittle materials by the Lattice Discrete "
               "Element Method (Riera's cubic truss lattice, explicit dynamics, bilinear "
               "softening bars, full energy balance).\n\nA case is a TOML file "
               "(docs/case-format.md); `ldem run CASE.toml` writes energies, events, probes, "
               "ParaView files and plots to an output folder.",
               "ldem"};
  app.set_version_flag("--version", std::string("ldem ") + kVersion);
  app.require_subcommand(0, 1);

  std::string case_path;
  ldem::RunOptions run;
  auto* cmd_run = app.add_subcommand("run", "Run a case and write its output folder");
  cmd_run->add_option("case", case_path, "Case file (TOML)")->required();
  cmd_run
      ->add_option("--out", run.out_dir,
                   "Output folder (default: results/<case file name without .toml>)")
      ->check(kNonEmpty);
  cmd_run
      ->add_option("--threads", run.threads,
                   "OpenMP threads (0: this run's share of the cores, among the ldem runs on "
                   "the machine)")
      ->check(threads_check);
  cmd_run->add_flag("--force", run.force, "Write into a non-empty output folder");
  std::vector<int> ensemble_member; // (hidden: how `ldem ensemble` starts its runs)
  cmd_run->add_option("--ensemble-member", ensemble_member, "Run I of N of an ensemble")
      ->expected(2)
      ->group("");
  bool no_plot = false;
  cmd_run->add_flag("--no-plot", no_plot, "Do not make the PNG plots");
  cmd_run
      ->add_option("--checkpoint-every", run.checkpoint_every,
                   "Steps between checkpoints (overrides output.checkpoint_every)")
      ->check(whole_in(0, 1000000000000000000LL));
  cmd_run
      ->add_option("--checkpoint-seconds", run.checkpoint_seconds,
                   "Wall-clock seconds between checkpoints (overrides "
                   "output.checkpoint_seconds; 0: never by time)")
      ->check(finite_at_least(0.0));
  // Under mpirun: how the processes share the body (boxes over y and z).
  std::vector<int> process_grid;
  const auto add_grid_option = [&](CLI::App* cmd) {
    cmd->add_option("--process-grid", process_grid,
                    "Under mpirun: processes along y and along z, whose product is the number "
                    "of processes (default: the grid that cuts the fewest modules)")
        ->expected(2)
        ->check(whole_in(1, 65536));
  };
  add_grid_option(cmd_run);

  auto* cmd_check = app.add_subcommand(
      "check", "Validate a case and print it resolved (node and bar counts, dt and its limit, "
               "K_r, L_cr) without running it");
  cmd_check->add_option("case", case_path, "Case file (TOML)")->required();

  std::string resume_dir;
  int resume_threads = 0;
  bool resume_no_plot = false;
  std::optional<double> resume_end;
  auto* cmd_resume = app.add_subcommand(
      "resume", "Continue an interrupted run from its checkpoint, or run a finished one further "
                "(--end); the outputs continue as if the run had never stopped");
  cmd_resume->add_option("dir", resume_dir, "Output folder of the run")->required();
  cmd_resume->add_option("--end", resume_end,
                         "Run to this time [s] instead of the run's end (a time after the "
                         "checkpoint's; a finished run continues from its end checkpoint)");
  std::string resume_case;
  cmd_resume
      ->add_option("--case", resume_case,
                   "Go on under this case file: other supports, velocities, loads, node "
                   "sets or end time, the same body, material, pre-cracks and probes")
      ->check(CLI::ExistingFile);
  cmd_resume
      ->add_option("--threads", resume_threads,
                   "OpenMP threads (0: this run's share of the cores, among the ldem runs "
                   "on the machine)")
      ->check(threads_check);
  cmd_resume->add_flag("--no-plot", resume_no_plot, "Do not make the PNG plots");
  add_grid_option(cmd_resume);

  std::string plot_dir;
  auto* cmd_plot =
      app.add_subcommand("plot", "Make crack.png, energy.png (and fields.png) of an output folder");
  cmd_plot->add_option("dir", plot_dir, "Output folder of a run")->required();
  std::string plot_view, plot_slice;
  cmd_plot->add_option("--view", plot_view,
                       "crack.png: every bar projected on this plane (xz, xy or yz); default the "
                       "face-on plane of a thin body, the crack face on and a slice across it "
                       "for a 3-D body");
  cmd_plot->add_option("--slice", plot_slice,
                       "crack.png: only the bars within half a module of the plane AXIS=VALUE "
                       "(VALUE in m; for example y=0.015)");

  std::string analyze_what, analyze_dir;
  auto* cmd_analyze = app.add_subcommand(
      "analyze", "Analyse a run's output folder: `ldem analyze crack DIR` finds the crack path, "
                 "the tip and its speed, and branching (crack_tip.csv, analysis.crack in "
                 "summary.json); `ldem analyze fatigue DIR` measures subcritical growth under a "
                 "cyclic load: the damage front a(t), a(N), da/dN, Delta K and Paris' law "
                 "(fatigue.csv, analysis.fatigue in summary.json)");
  cmd_analyze->add_option("what", analyze_what, "What to analyse")
      ->required()
      ->check(CLI::IsMember({"crack", "fatigue"}));
  cmd_analyze->add_option("dir", analyze_dir, "Output folder of a run")->required();
  std::string analyze_window;
  cmd_analyze
      ->add_option("--window", analyze_window,
                   "fatigue: representative points over the cycles at constant "
                   "amplitude (\"constant\") or every cycle (\"cycles\"); default "
                   "the case's analysis.fatigue_window")
      ->check(CLI::IsMember({"constant", "cycles"}));
  std::string analyze_rate;
  cmd_analyze
      ->add_option("--rate", analyze_rate,
                   "fatigue: da/dN between representative points evenly spaced in N "
                   "(\"points\", as the paper) or between consecutive front steps "
                   "(\"secant\"); default the case's analysis.fatigue_rate")
      ->check(CLI::IsMember({"points", "secant"}));

  ldem::EnsembleOptions ens;
  bool ens_no_plot = false;
  auto* cmd_ensemble = app.add_subcommand(
      "ensemble", "Run each case several times under admissible perturbations (step between 0.5 "
                  "and 0.6 L/c, a 1e-12 relative change of the imposed velocities, the pre-crack "
                  "mirrored about its node plane), analyse every crack, and tabulate them with "
                  "their median and range (ensemble.md, ensemble.csv)");
  cmd_ensemble->add_option("cases", ens.cases, "Case files (TOML)")->required();
  cmd_ensemble->add_option("--runs", ens.runs, "Runs per case")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd_ensemble->add_option("--out", ens.out_dir, "Output folder")
      ->check(kNonEmpty)
      ->capture_default_str();
  cmd_ensemble
      ->add_option("--threads", ens.threads, "OpenMP threads per run (0: a share of the cores)")
      ->check(threads_check);
  cmd_ensemble
      ->add_option("--jobs", ens.jobs,
                   "Runs at once (0: as many as the cores, or the cores over --threads); the "
                   "runs share the cores unless --threads is given")
      ->check(CLI::Range(0, 4096));
  cmd_ensemble->add_flag("--force", ens.force, "Write into a non-empty output folder");
  cmd_ensemble->add_flag("--no-plot", ens_no_plot, "Do not make the PNG plots");

  int modes_count = 6, modes_threads = 0;
  auto* cmd_modes = app.add_subcommand(
      "modes", "Print the lowest eigenfrequencies of a case's lattice (undamaged bars, free DOF, "
               "pre-cracked bars left out) with their periods and x/y/z participation, and "
               "compare the lowest with the time step and the load frequency; no files");
  cmd_modes->add_option("case", case_path, "Case file (TOML)")->required();
  cmd_modes->add_option("--count", modes_count, "Number of modes")->capture_default_str();
  cmd_modes->add_option("--threads", modes_threads, "OpenMP threads (0: all cores)")
      ->check(threads_check);

  auto* cmd_format =
      app.add_subcommand("case-format", "Print the case-file reference (docs/case-format.md)");

  ldem::BenchOptions bench;
  std::vector<unsigned> modules{64, 64, 64};
  auto* cmd_bench = app.add_subcommand(
      "bench", "Time elastic dynamics of a free 3-D lattice (small imposed strain rate); the last "
               "line reports bar updates per second over the time-step loop");
  cmd_bench->add_option("--modules", modules, "Modules along x, y, z")
      ->expected(3)
      ->check(whole_in(1, 100000))
      ->capture_default_str();
  cmd_bench->add_option("--steps", bench.steps, "Time steps to time")
      ->check(CLI::Range(2, 1000000000))
      ->capture_default_str();
  cmd_bench->add_option("--threads", bench.threads, "OpenMP threads (0: all cores)")
      ->check(threads_check)
      ->capture_default_str();
  add_grid_option(cmd_bench);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end with 0; every usage error with 2, as bad input does.
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (app.get_subcommands().empty()) {
    std::cout << app.help();
    return 0;
  }
  // Several processes (mpirun -np P): `ldem run`, `ldem resume` and `ldem bench` are
  // distributed; anything else would do the same work P times.
  if (ldem::process_count() > 1 && !cmd_bench->parsed() && !cmd_run->parsed() &&
      !cmd_resume->parsed()) {
    if (ldem::process_rank() == 0)
      fmt::print(stderr,
                 "ldem: error: `ldem {}` runs in one process ({} were started); with MPI, "
                 "`ldem run`, `ldem resume` and `ldem bench` are distributed. Start it without "
                 "mpirun and give it the cores with --threads\n",
                 app.get_subcommands().front()->get_name(), ldem::process_count());
    return 2;
  }
  const int grid_y = process_grid.empty() ? 0 : process_grid[0];
  const int grid_z = process_grid.empty() ? 0 : process_grid[1];
  if (!process_grid.empty() && grid_y * grid_z != ldem::process_count()) {
    if (ldem::process_rank() == 0)
      fmt::print(stderr,
                 "ldem: error: --process-grid {} {}: expected two numbers whose product is the "
                 "number of processes started, {}\n",
                 grid_y, grid_z, ldem::process_count());
    return 2;
  }
  try {
    if (cmd_run->parsed()) {
      run.grid_y = grid_y;
      run.grid_z = grid_z;
      if (run.out_dir.empty()) {
        std::string stem = case_path.substr(case_path.find_last_of('/') + 1);
        if (stem.size() > 5 && stem.substr(stem.size() - 5) == ".toml")
          stem.resize(stem.size() - 5);
        run.out_dir = "results/" + stem;
      }
      run.plots = !no_plot;
      if (ensemble_member.size() == 2)
        run.adjust = ldem::ensemble_adjust(ensemble_member[0], ensemble_member[1]);
      return ldem::run_command(case_path, run);
    }
    if (cmd_resume->parsed())
      return ldem::resume_command(resume_dir, resume_threads, !resume_no_plot, grid_y, grid_z,
                                  resume_end, resume_case);
    if (cmd_check->parsed())
      return ldem::check_command(case_path);
    if (cmd_plot->parsed())
      return ldem::plot_command(plot_dir, plot_view, plot_slice);
    if (cmd_modes->parsed())
      return ldem::modes_command(case_path, modes_count, modes_threads);
    if (cmd_ensemble->parsed()) {
      ens.plots = !ens_no_plot;
      return ldem::ensemble_command(ens);
    }
    if (cmd_analyze->parsed()) {
      if (analyze_what == "fatigue")
        fmt::print("{}\n", ldem::fatigue_report(ldem::analyze_fatigue_dir(
                               analyze_dir, analyze_window, analyze_rate)));
      else
        fmt::print("{}\n", ldem::crack_report(ldem::analyze_crack_dir(analyze_dir)));
      return 0;
    }
    if (cmd_format->parsed()) {
      std::cout << ldem::case_format_markdown();
      return 0;
    }
    if (cmd_bench->parsed()) {
      bench.nx = modules[0];
      bench.ny = modules[1];
      bench.nz = modules[2];
      bench.grid_y = grid_y;
      bench.grid_z = grid_z;
      const ldem::BenchResult r = ldem::run_bench(bench);
      fmt::print("lattice {} x {} x {}: dt = {:.4g} s (stable {:.4g} s), {:.1f} bytes/module, "
                 "energy drift {:.2e}\n",
                 bench.nx, bench.ny, bench.nz, r.dt, r.dt_stable, r.bytes_per_module,
                 r.energy_drift);
      if (r.resident_steps > 0.0 && r.resident_peak > 0.0)
        fmt::print("resident memory{}: {:.3g} GB after the steps, peak {:.3g} GB ({:.2f} "
                   "times; the set-up included)\n",
                   r.processes > 1 ? " of the busiest process" : "", r.resident_steps / 1e9,
                   r.resident_peak / 1e9, r.resident_peak / r.resident_steps);
      fmt::print("{}\n", ldem::bench_line(r));
    }
  } catch (const ldem::InputError& e) {
    fmt::print(stderr, "ldem: error: {}\n", e.what());
    return 2;
  }
  return 0;
}
