// `ldem ensemble`: runs of each case under admissible perturbations, and their table.
#include "app/ensemble.hpp"

#include "app/case_run.hpp"
#include "io/case_spec.hpp"
#include "io/output.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <omp.h>
#include <spawn.h>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

#ifndef LDEM_PLOT_SCRIPT
#define LDEM_PLOT_SCRIPT "tools/plot/ldem_plot.py"
#endif

namespace fs = std::filesystem;

namespace ldem {

Perturbation perturbation(int i, int n) {
  Perturbation p;
  p.courant = n > 1 ? 0.6 - 0.1 * i / (n - 1) : 0.6;
  p.velocity_eps = i == 0 ? 0.0 : (i % 2 ? -1e-12 : 1e-12);
  p.mirror_precrack = (i / 2) % 2 == 1;
  return p;
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The case changed as run i of n asks; the crack analysis on.
void apply(CaseSpec& s, const Perturbation& p, bool keep_vtu) {
  s.step.rule = TimeStep::Rule::Paper;
  s.step.courant = p.courant;
  for (VelocitySpec& v : s.velocities) {
    v.value.x *= 1.0 + p.velocity_eps;
    v.value.y *= 1.0 + p.velocity_eps;
    v.value.z *= 1.0 + p.velocity_eps;
  }
  if (p.mirror_precrack)
    for (PrecrackSpec& c : s.precracks) {
      // The rectangle's normal axis, and its offset from the nearest plane of nodes.
      const Vec3& a = c.rect.edge1;
      const Vec3& b = c.rect.edge2;
      const double nrm[3] = {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
      int k = 0;
      for (int j = 1; j < 3; ++j)
        if (std::abs(nrm[j]) > std::abs(nrm[k]))
          k = j;
      double& x = k == 0 ? c.rect.origin.x : k == 1 ? c.rect.origin.y : c.rect.origin.z;
      const double plane = std::round(x / s.L) * s.L;
      x = plane - (x - plane);
    }
  s.analysis.crack = true;
  if (!keep_vtu)
    s.output.vtu = false;
}

std::string stem_of(const std::string& path) {
  std::string stem = fs::path(path).filename().string();
  if (stem.size() > 5 && stem.substr(stem.size() - 5) == ".toml")
    stem.resize(stem.size() - 5);
  return stem;
}

nlohmann::ordered_json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw InputError(fmt::format("{}: cannot read", path));
  return nlohmann::ordered_json::parse(in);
}

// The last row of energy.csv: time, W, U, K, D, Dc, error.
std::vector<double> last_energy(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty())
      last = line;
  std::vector<double> v;
  std::istringstream ls(last);
  std::string f;
  while (std::getline(ls, f, ','))
    v.push_back(std::stod(f));
  if (v.size() < 7)
    throw InputError(fmt::format("{}: no energy rows", path));
  return v;
}

struct Row {
  std::string case_name, title;
  int run = 0;
  Perturbation p;
  double dt = 0, branching_mm = kNaN, upper_deg = kNaN, lower_deg = kNaN;
  int branches = 0, open = 0;
  bool secondary = false;
  double speed = 0, speed_over_cR = 0, length_mm = 0, speed_branch = kNaN, cR = 0;
  double speed_median = 0, speed_unflagged = 0;
  double W = 0, U = 0, K = 0, D = 0, balance = 0, wall = 0;
};

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty())
    return kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string range(std::vector<double> v, const char* f) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty())
    return "-";
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return fmt::format(fmt::runtime(std::string("{:") + f + "} to {:" + f + "}"), *lo, *hi);
}

std::string num(double x, const char* f) {
  return std::isnan(x) ? "-" : fmt::format(fmt::runtime(std::string("{:") + f + "}"), x);
}

// The median of the measured values, with how many runs measured one when some did not.
std::string measured_median(const std::vector<double>& v, const char* f) {
  const auto n = static_cast<std::size_t>(
      std::count_if(v.begin(), v.end(), [](double x) { return !std::isnan(x); }));
  const std::string m = num(median(v), f);
  return n == v.size() || n == 0 ? m : fmt::format("{} ({} of {} runs)", m, n, v.size());
}

// SIGINT or SIGTERM to the ensemble's own process: no new run starts, and the runs going on are
// asked to stop (each at a step boundary, with its checkpoint).
volatile std::sig_atomic_t g_ensemble_stop = 0;
void on_ensemble_signal(int sig) {
  g_ensemble_stop = sig;
}

// A run of the ensemble, as a process of its own.
struct Job {
  std::size_t k = 0; // its case
  int i = 0;         // its perturbation
  std::string out, log;
  pid_t pid = 0;
  int rc = -1;
  std::chrono::steady_clock::time_point start;
};

// This program's path (the runs are started as `ldem run`, so that their command name is
// ldem's: util/core_share.hpp counts them).
std::string own_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec)
    throw InputError(fmt::format("ensemble: cannot find this program's path: {}", ec.message()));
  return p.string();
}

// The last lines of a run's log, for the message of a failed run.
std::string log_tail(const std::string& path, std::size_t lines) {
  std::ifstream in(path);
  std::vector<std::string> all;
  for (std::string line; std::getline(in, line);)
    if (line.find('\r') == std::string::npos) // (a progress bar's line)
      all.push_back(line);
  std::string s;
  for (std::size_t q = all.size() > lines ? all.size() - lines : 0; q < all.size(); ++q)
    s += "  " + all[q] + "\n";
  return s;
}

} // namespace

std::function<void(CaseSpec&)> ensemble_adjust(int i, int n) {
  return [i, n](CaseSpec& s) { apply(s, perturbation(i, n), i == 0); };
}

int ensemble_command(const EnsembleOptions& o) {
  if (o.cases.empty())
    throw InputError("ensemble: expected at least one case file, got none");
  if (o.runs < 1)
    throw InputError(fmt::format("ensemble: --runs: expected at least 1, got {}", o.runs));
  std::vector<std::string> stems;
  for (const std::string& c : o.cases) {
    stems.push_back(stem_of(c));
    if (std::count(stems.begin(), stems.end(), stems.back()) > 1)
      throw InputError(fmt::format("ensemble: two cases named {}: their run folders would "
                                   "collide; rename one",
                                   stems.back()));
  }
  // Every case and every perturbation is checked before anything is written.
  for (const std::string& c : o.cases)
    for (int i : {0, std::min(2, o.runs - 1), o.runs - 1})
      build_case(c, [&](CaseSpec& s) { apply(s, perturbation(i, o.runs), true); });
  std::error_code ec;
  if (fs::exists(o.out_dir) && !fs::is_empty(o.out_dir, ec) && !o.force)
    throw InputError(fmt::format("{}: the output folder exists and is not empty; use --force to "
                                 "write into it",
                                 o.out_dir));
  fs::create_directories(o.out_dir, ec);
  if (ec)
    throw InputError(
        fmt::format("{}: cannot create the output folder: {}", o.out_dir, ec.message()));

  // The runs, side by side: each a process of its own (`ldem run --ensemble-member I N`), its
  // output in its folder's log; `jobs` at once, sharing the cores (or with --threads each).
  const int cores = omp_get_num_procs();
  const int at_once = o.jobs > 0 ? o.jobs : std::max(1, o.threads > 0 ? cores / o.threads : cores);
  const std::string self = own_path();
  std::vector<Job> jobs;
  for (std::size_t k = 0; k < o.cases.size(); ++k) {
    fs::create_directories(fs::path(o.out_dir) / stems[k], ec);
    for (int i = 0; i < o.runs; ++i) {
      Job j;
      j.k = k;
      j.i = i;
      j.out = fmt::format("{}/{}/run_{:02d}", o.out_dir, stems[k], i);
      j.log = j.out + ".log";
      jobs.push_back(j);
    }
  }
  fmt::print(stderr,
             "ldem: ensemble of {} runs, {} at a time on {} cores; each run's output in "
             "its folder's .log\n",
             jobs.size(), std::min<std::size_t>(jobs.size(), static_cast<std::size_t>(at_once)),
             cores);
  struct sigaction act = {}, old_int = {}, old_term = {};
  act.sa_handler = on_ensemble_signal; // (no SA_RESTART: waitpid returns at a signal)
  sigemptyset(&act.sa_mask);
  g_ensemble_stop = 0;
  sigaction(SIGINT, &act, &old_int);
  sigaction(SIGTERM, &act, &old_term);
  std::size_t next = 0, running = 0;
  int failed = 0;
  const auto start = [&](Job& j) {
    std::vector<std::string> args = {self,
                                     "run",
                                     o.cases[j.k],
                                     "--out",
                                     j.out,
                                     "--ensemble-member",
                                     std::to_string(j.i),
                                     std::to_string(o.runs)};
    if (o.threads > 0)
      args.insert(args.end(), {"--threads", std::to_string(o.threads)});
    if (o.force)
      args.emplace_back("--force");
    if (!o.plots)
      args.emplace_back("--no-plot");
    std::vector<char*> argv;
    for (std::string& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t files;
    posix_spawn_file_actions_init(&files);
    posix_spawn_file_actions_addopen(&files, 1, j.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&files, 1, 2);
    const int err = posix_spawn(&j.pid, self.c_str(), &files, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&files);
    if (err != 0)
      throw InputError(fmt::format("ensemble: cannot start {}: {}", self, std::strerror(err)));
    j.start = std::chrono::steady_clock::now();
    const Perturbation p = perturbation(j.i, o.runs);
    fmt::print(stderr,
               "ldem: ensemble {} run {}/{}: Courant {:.4f}, velocity x (1 {:+.0e}), pre-crack "
               "{}: started\n",
               stems[j.k], j.i + 1, o.runs, p.courant, p.velocity_eps,
               p.mirror_precrack ? "mirrored" : "as given");
    ++running;
  };
  bool stop_sent = false;
  while (running > 0 || (next < jobs.size() && !failed && !g_ensemble_stop)) {
    while (next < jobs.size() && running < static_cast<std::size_t>(at_once) && !failed &&
           !g_ensemble_stop)
      start(jobs[next++]);
    int status = 0;
    const pid_t done = waitpid(-1, &status, 0);
    if (done < 0) {
      if (errno != EINTR)
        break;
      if (g_ensemble_stop && !stop_sent) { // (a Ctrl-C reaches the runs from the terminal too)
        for (const Job& j : jobs)
          if (j.pid > 0 && j.rc < 0)
            kill(j.pid, SIGTERM);
        stop_sent = true;
      }
      continue;
    }
    for (Job& j : jobs)
      if (j.pid == done) {
        j.rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        --running;
        const double wall =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - j.start).count();
        if (j.rc == 0)
          fmt::print(stderr, "ldem: ensemble {} run {}/{}: done in {:.1f} s\n", stems[j.k], j.i + 1,
                     o.runs, wall);
        else {
          fmt::print(stderr, "ldem: ensemble {} run {}/{}: ended with code {} ({}):\n{}",
                     stems[j.k], j.i + 1, o.runs, j.rc, j.log, log_tail(j.log, 5));
          if (!failed)
            failed = j.rc;
        }
      }
  }
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  if (failed)
    return failed;
  if (g_ensemble_stop) {
    fmt::print(stderr, "ldem: ensemble stopped; the runs that were going on hold checkpoints "
                       "(ldem resume DIR/CASE/run_NN)\n");
    return 128 + g_ensemble_stop;
  }

  std::vector<Row> rows;
  for (const Job& j : jobs) {
    const std::size_t k = j.k;
    const int i = j.i;
    const Perturbation p = perturbation(i, o.runs);
    const std::string summary_file = j.out + "/summary.json";
    nlohmann::ordered_json summary = read_json(summary_file); // keeps the file's key order
    summary["perturbation"] = {{"run", i},
                               {"courant", p.courant},
                               {"velocity_relative_change", p.velocity_eps},
                               {"precrack_mirrored", p.mirror_precrack}};
    write_file(summary_file, summary.dump(2) + "\n");

    Row r;
    r.case_name = stems[k];
    r.title = summary.value("title", "");
    r.run = i;
    r.p = p;
    r.dt = summary["dt"].get<double>();
    r.wall = summary["wall_s"].get<double>();
    r.balance = summary["max_balance_error"].get<double>();
    const auto& c = summary["analysis"]["crack"];
    if (!c["branching_length_m"].is_null()) {
      r.branching_mm = c["branching_length_m"].get<double>() * 1e3;
      double hi = -1e9, lo = 1e9;
      for (const auto& a : c["branch_angles_deg"]) {
        hi = std::max(hi, a.get<double>());
        lo = std::min(lo, a.get<double>());
      }
      r.upper_deg = hi;
      r.lower_deg = lo;
    }
    for (const auto& b : c["branches"])
      if (b["level"].get<int>() == 1) {
        ++r.branches;
        r.open += b["opens"].get<bool>();
      }
    r.secondary = c["secondary_branching"].get<bool>();
    r.speed = c["max_crack_speed_m_s"].get<double>();
    r.cR = c["rayleigh_speed_m_s"].get<double>();
    if (!c["speed_before_branching_m_s"].is_null())
      r.speed_branch = c["speed_before_branching_m_s"].get<double>();
    r.speed_over_cR = c["max_crack_speed_over_rayleigh"].get<double>();
    // null: no window of the kind (an arrested or short crack).
    auto speed_or_nan = [](const auto& v) {
      return v.is_null() ? std::numeric_limits<double>::quiet_NaN() : v.template get<double>();
    };
    r.speed_median = speed_or_nan(c["median_crack_speed_m_s"]);
    r.speed_unflagged = speed_or_nan(c["max_unflagged_crack_speed_m_s"]);
    r.length_mm = c["final_crack_length_m"].get<double>() * 1e3;
    const std::vector<double> e = last_energy(j.out + "/energy.csv");
    r.W = e[1];
    r.U = e[2];
    r.K = e[3];
    r.D = e[4];
    rows.push_back(r);
  }

  // The table: every run, then median and range per case.
  std::string csv =
      "case,run,courant,dt,velocity_relative_change,precrack_mirrored,"
      "branching_length_mm,upper_branch_angle_deg,lower_branch_angle_deg,branches,"
      "branches_open,secondary_branching,speed_before_branching_m_s,max_crack_speed_m_s,"
      "max_speed_over_rayleigh,median_crack_speed_m_s,max_unflagged_crack_speed_m_s,"
      "crack_length_mm,external_work_J,elastic_J,"
      "kinetic_J,dissipated_J,max_balance_error,wall_s\n";
  for (const Row& r : rows)
    csv += fmt::format(
        "{},{},{:.4f},{:.6g},{:g},{},{},{},{},{},{},{},{},{:.6g},{:.4f},{:.6g},{:.6g},"
        "{:.5g},{:.6g},"
        "{:.6g},{:.6g},{:.6g},{:.4g},{:.3f}\n",
        r.case_name, r.run, r.p.courant, r.dt, r.p.velocity_eps,
        r.p.mirror_precrack ? "true" : "false", num(r.branching_mm, ".4f"), num(r.upper_deg, ".2f"),
        num(r.lower_deg, ".2f"), r.branches, r.open, r.secondary ? "true" : "false",
        num(r.speed_branch, ".6g"), r.speed, r.speed_over_cR, r.speed_median, r.speed_unflagged,
        r.length_mm, r.W, r.U, r.K, r.D, r.balance, r.wall);
  write_file(o.out_dir + "/ensemble.csv", csv);

  std::string md = fmt::format(
      "# Ensemble: {} runs per case\n\nRun i uses the paper's step rule with Courant number "
      "0.6 - 0.1 i / (n - 1), the imposed velocities times 1 + eps (eps = 0, then -1e-12 and "
      "+1e-12 alternately) and the pre-crack as given (runs 0, 1, 4, 5) or mirrored about its "
      "node plane (runs 2, 3, 6, 7). Branching length: from the mouth of the pre-crack to the "
      "first bifurcation; angles of the uppermost and lowermost branch of that bifurcation to "
      "the pre-crack direction; open: branches that reach a border of the body. Speeds: tip "
      "speeds of the trunk and the branches, each fitted over speed_fit_length of advance; "
      "every speed leaves out the windows where the tip jumps; max unmarked also those where "
      "the softened zone runs far ahead of the tip at some sample; the median takes the "
      "windows in which the crack runs (docs/model.md, 8b); -: none measured. Energies at the "
      "end time, in uJ.\n",
      o.runs);
  for (std::size_t k = 0; k < o.cases.size(); ++k) {
    std::vector<const Row*> rs;
    for (const Row& r : rows)
      if (r.case_name == stems[k])
        rs.push_back(&r);
    md += fmt::format("\n## {} ({})\n\n", stems[k], rs.front()->title);
    md += "| run | Courant | pre-crack | branching [mm] | upper [deg] | lower [deg] | branches "
          "(open) | secondary | speed to branching / c_R | max speed / c_R | max unmarked / c_R | "
          "median speed / c_R | crack [mm] | U | K | D | balance | wall [s] |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Row* r : rs)
      md += fmt::format("| {} | {:.4f} | {} | {} | {} | {} | {} ({}) | {} | {} | {:.2f} | "
                        "{} | {} | {:.3g} | {:.1f} | {:.1f} | {:.1f} | {:.2g} | {:.2f} |\n",
                        r->run, r->p.courant, r->p.mirror_precrack ? "mirrored" : "as given",
                        num(r->branching_mm, ".3f"), num(r->upper_deg, ".1f"),
                        num(r->lower_deg, ".1f"), r->branches, r->open, r->secondary ? "yes" : "no",
                        num(r->speed_branch / r->cR, ".2f"), r->speed_over_cR,
                        num(r->speed_unflagged / r->cR, ".2f"), num(r->speed_median / r->cR, ".2f"),
                        r->length_mm, r->U * 1e6, r->K * 1e6, r->D * 1e6, r->balance, r->wall);
    auto col = [&](auto f) {
      std::vector<double> v;
      for (const Row* r : rs)
        v.push_back(f(*r));
      return v;
    };
    const auto bl = col([](const Row& r) { return r.branching_mm; });
    const auto up = col([](const Row& r) { return r.upper_deg; });
    const auto lo = col([](const Row& r) { return r.lower_deg; });
    const auto sp = col([](const Row& r) { return r.speed_branch / r.cR; });
    const auto sr = col([](const Row& r) { return r.speed_over_cR; });
    const auto su = col([](const Row& r) { return r.speed_unflagged / r.cR; });
    const auto sm = col([](const Row& r) { return r.speed_median / r.cR; });
    const auto ln = col([](const Row& r) { return r.length_mm; });
    const auto U = col([](const Row& r) { return r.U * 1e6; });
    const auto K = col([](const Row& r) { return r.K * 1e6; });
    const auto D = col([](const Row& r) { return r.D * 1e6; });
    const auto B = col([](const Row& r) { return r.balance; });
    int branched = 0, secondary = 0;
    for (const Row* r : rs) {
      branched += !std::isnan(r->branching_mm);
      secondary += r->secondary;
    }
    md += fmt::format("| median | | | {} | {} | {} | {} of {} branched | {} of {} | {} | "
                      "{:.2f} | {} | {} | {:.3g} | {:.1f} | {:.1f} | {:.1f} | {:.2g} | |\n",
                      num(median(bl), ".3f"), num(median(up), ".1f"), num(median(lo), ".1f"),
                      branched, rs.size(), secondary, rs.size(), measured_median(sp, ".2f"),
                      median(sr), measured_median(su, ".2f"), measured_median(sm, ".2f"),
                      median(ln), median(U), median(K), median(D), median(B));
    md += fmt::format("| range | | | {} | {} | {} | | | {} | {} | {} | {} | {} | {} | {} | {} | {} "
                      "| |\n",
                      range(bl, ".3f"), range(up, ".1f"), range(lo, ".1f"), range(sp, ".2f"),
                      range(sr, ".2f"), range(su, ".2f"), range(sm, ".2f"), range(ln, ".3g"),
                      range(U, ".1f"), range(K, ".1f"), range(D, ".1f"), range(B, ".2g"));
  }
  write_file(o.out_dir + "/ensemble.md", md);
  if (o.plots) {
    const std::string cmd =
        fmt::format("/usr/bin/python3 '{}' --ensemble '{}'", LDEM_PLOT_SCRIPT, o.out_dir);
    if (std::system(cmd.c_str()) != 0)
      fmt::print(stderr,
                 "ldem: warning: the ensemble's pictures failed ({}); the tables are "
                 "complete\n",
                 plot_failure_reason());
  }
  fmt::print(stderr, "ldem: ensemble done: {} runs, table in {}/ensemble.md and ensemble.csv\n",
             rows.size(), o.out_dir);
  return 0;
}

} // namespace ldem
