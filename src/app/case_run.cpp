#include "app/case_run.hpp"

#include "analysis/crack.hpp"
#include "analysis/fatigue.hpp"
#include "app/run_body.hpp"
#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "parallel/comm.hpp"
#include "solver/modes.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <omp.h>
#include <sstream>
#include <toml++/toml.h>
#include <unistd.h>
#include <variant>

#ifndef LDEM_PLOT_SCRIPT
#define LDEM_PLOT_SCRIPT "tools/plot/ldem_plot.py"
#endif

namespace ldem {

namespace fs = std::filesystem;

namespace {

// The signal that asked the run to stop (SIGINT or SIGTERM), 0 while none has.
std::atomic<int> g_interrupted{0};
void on_signal(int sig) {
  g_interrupted = sig;
}

std::vector<index_t> select(const Lattice& lat, const NodeSetSpec& s) {
  switch (s.kind) {
  case NodeSetSpec::Kind::Face:
    return select_face(lat, s.face);
  case NodeSetSpec::Kind::FaceCentres:
    return select_face_module_centres(lat, s.face);
  case NodeSetSpec::Kind::Box:
    return select_box(lat, s.lo, s.hi);
  case NodeSetSpec::Kind::All:
    break;
  }
  return select_all(lat);
}

std::string how(const NodeSetSpec& s) {
  switch (s.kind) {
  case NodeSetSpec::Kind::Face:
    return "face " + face_name(s.face);
  case NodeSetSpec::Kind::FaceCentres:
    return "centres of the modules along face " + face_name(s.face);
  case NodeSetSpec::Kind::Box:
    return fmt::format("box [{:g}, {:g}, {:g}] to [{:g}, {:g}, {:g}]", s.lo.x, s.lo.y, s.lo.z,
                       s.hi.x, s.hi.y, s.hi.z);
  case NodeSetSpec::Kind::All:
    break;
  }
  return "all nodes";
}

std::string dofs_text(DofMask m) {
  std::string s;
  for (int d = 0; d < 3; ++d)
    if (m & (1u << d))
      s += static_cast<char>('x' + d);
  return s;
}

} // namespace

const NodeSet& set_named(const std::vector<NodeSet>& sets, const std::string& name) {
  for (const NodeSet& s : sets)
    if (s.name == name)
      return s;
  throw InputError("node set \"" + name + "\" is not defined");
}

BuiltCase build_case(const std::string& path, const std::function<void(CaseSpec&)>& adjust,
                     bool with_simulation) {
  BuiltCase c;
  c.spec = read_case(path);
  if (adjust)
    adjust(c.spec);
  const CaseSpec& s = c.spec;
  try {
    Lattice lat(s.nx, s.ny, s.nz, s.L);
    for (const NodeSetSpec& ns : s.node_sets)
      c.sets.push_back(make_node_set(ns.name, select(lat, ns), how(ns)));
    for (const PrecrackSpec& p : s.precracks) {
      c.cuts.push_back(cut_bars(lat, p.rect, p.nudge));
      c.precracked.insert(c.precracked.end(), c.cuts.back().bars.begin(), c.cuts.back().bars.end());
    }
    std::sort(c.precracked.begin(), c.precracked.end());
    c.precracked.erase(std::unique(c.precracked.begin(), c.precracked.end()), c.precracked.end());
    Conditions cond;
    cond.plane_strain_axis = s.plane_strain_axis;
    for (const FixedSpec& f : s.fixed)
      cond.fixed.push_back({set_named(c.sets, f.set), f.dofs});
    for (const VelocitySpec& v : s.velocities)
      cond.velocities.push_back({set_named(c.sets, v.set), v.dofs, v.value, v.scale});
    for (const LoadSpec& l : s.loads)
      cond.loads.push_back({set_named(c.sets, l.set), l.force, l.scale});
    for (const ProbeSpec& p : s.probes) {
      index_t best = 0;
      if (p.kind == ProbeSpec::Kind::BarForce) {
        double d_best = INFINITY;
        for (index_t b = 0; b < lat.num_bars(); ++b) {
          const Vec3 m = lat.bar_centre(b);
          const double d = (m.x - p.at.x) * (m.x - p.at.x) + (m.y - p.at.y) * (m.y - p.at.y) +
                           (m.z - p.at.z) * (m.z - p.at.z);
          if (d < d_best) {
            d_best = d;
            best = b;
          }
        }
      }
      c.probe_bars.push_back(best);
    }
    BarFields fields;
    const std::pair<const std::optional<Field>*, std::vector<double>*> props[] = {
        {&s.fields.E, &fields.E},
        {&s.fields.Gf, &fields.Gf},
        {&s.fields.e_p, &fields.e_p},
        {&s.fields.e_r, &fields.e_r},
        {&s.fields.R_f, &fields.R_f}};
    const char* names[] = {"material.E", "material.Gf", "material.e_p", "material.e_r",
                           "material.R_f"};
    // Evaluated over the whole body only where it is built: a distributed run's other
    // processes evaluate their windows (run_body_distributed.cpp).
    for (int i = 0; i < 5; ++i)
      if (const auto& f = *props[i].first) {
        validate_field(*f, lat, names[i]);
        if (with_simulation)
          *props[i].second = evaluate_field(*f, lat);
      }
    if (s.fields.rho) {
      validate_field(*s.fields.rho, lat, "material.rho");
      if (with_simulation)
        fields.rho = evaluate_field_modules(*s.fields.rho, lat);
    }
    c.lattice = lat;
    c.conditions = cond;
    c.options.step = s.step;
    c.options.damping = s.damping;
    if (with_simulation) {
      BarTable table(lat, s.material, fields);
      c.warnings = table.warnings();
      c.sim = std::make_unique<Simulation>(std::move(lat), std::move(table), std::move(cond),
                                           c.options, c.precracked);
    }
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", path, e.what()));
  }
  c.path = path;
  if (c.sim)
    check_end_time(c, c.sim->dt());
  return c;
}

void check_end_time(const BuiltCase& c, double dt) {
  if (!(c.spec.end_time >= dt))
    throw InputError(fmt::format("{}: time.end: expected at least one time step ({:.4g} s), got "
                                 "{:g} s",
                                 c.path, dt, c.spec.end_time));
}

BodyNumbers body_numbers(const Simulation& sim) {
  return {sim.table().ranges(),   sim.table().ductility_summary(),
          sim.stable_step(),      sim.dt(),
          sim.bytes_per_module(), sim.table().per_bar()};
}

std::string resolved_case_toml(const BuiltCase& c, const BodyNumbers& body) {
  const CaseSpec& s = c.spec;
  const Lattice& lat = *c.lattice;
  auto vec = [](Vec3 v) { return toml::array{v.x, v.y, v.z}; };
  toml::table root;
  root.insert("case", toml::table{{"title", s.title}});
  root.insert("lattice",
              toml::table{{"modules", toml::array{s.nx, s.ny, s.nz}},
                          {"L", s.L},
                          {"plane_strain",
                           s.plane_strain_axis < 0
                               ? std::string("none")
                               : std::string(1, static_cast<char>('x' + s.plane_strain_axis))}});
  toml::table mat{{"law", "bilinear"},
                  {"E", s.material.E},
                  {"nu", s.material.nu},
                  {"rho", s.material.rho},
                  {"Gf", s.material.Gf},
                  {"single_ratio", s.material.single_ratio},
                  {"allow_low_kr", s.material.allow_low_kr}};
  if (s.material.e_p)
    mat.insert("e_p", *s.material.e_p);
  if (s.material.R_f)
    mat.insert("R_f", *s.material.R_f);
  if (s.material.e_r)
    mat.insert("e_r", *s.material.e_r);
  const std::pair<const char*, const std::optional<Field>*> field_of[] = {
      {"E", &s.fields.E},     {"Gf", &s.fields.Gf},   {"e_p", &s.fields.e_p},
      {"e_r", &s.fields.e_r}, {"R_f", &s.fields.R_f}, {"rho", &s.fields.rho}};
  toml::table fields_table;
  for (const auto& [name, f] : field_of)
    if (*f) {
      mat.insert_or_assign(name, describe_field(**f)); // the field, described in words
      if ((*f)->kind == Field::Kind::Weibull) {
        const double g = weibull_shape((*f)->cv);
        fields_table.insert(name, toml::table{{"kind", "weibull"},
                                              {"mean", (*f)->mean},
                                              {"cv", (*f)->cv},
                                              {"shape", g},
                                              {"scale", weibull_scale((*f)->mean, g)},
                                              {"correlation_length", (*f)->correlation_length}});
      } else {
        fields_table.insert(
            name, toml::table{{"kind", (*f)->kind == Field::Kind::Linear ? "linear" : "table"}});
      }
    }
  if (!fields_table.empty())
    root.insert("fields", fields_table);
  const MaterialRanges& mr = body.ranges;
  mat.insert("rule", mr.rule);
  mat.insert("E_range", toml::array{mr.E[0], mr.E[1]});
  mat.insert("Gf_range", toml::array{mr.Gf[0], mr.Gf[1]});
  mat.insert("e_p_range", toml::array{mr.e_p[0], mr.e_p[1]});
  mat.insert("e_r_normal_range", toml::array{mr.e_r_normal[0], mr.e_r_normal[1]});
  root.insert("material", mat);
  toml::array sets;
  for (std::size_t i = 0; i < s.node_sets.size(); ++i) {
    const NodeSetSpec& n = s.node_sets[i];
    toml::table t{{"name", n.name}};
    if (n.kind == NodeSetSpec::Kind::Face)
      t.insert("face", face_name(n.face));
    else if (n.kind == NodeSetSpec::Kind::FaceCentres)
      t.insert("face_centres", face_name(n.face));
    else if (n.kind == NodeSetSpec::Kind::Box) {
      t.insert("box_min", vec(n.lo));
      t.insert("box_max", vec(n.hi));
    } else
      t.insert("all", true);
    t.insert("nodes_selected", static_cast<std::int64_t>(c.sets[i].nodes.size()));
    sets.push_back(t);
  }
  if (!sets.empty())
    root.insert("node_set", sets);
  auto function = [](const TimeFunction& f) {
    toml::array terms;
    for (const TimeTerm& term : f.terms())
      std::visit(
          [&terms](const auto& t) {
            using T = std::decay_t<decltype(t)>;
            if constexpr (std::is_same_v<T, Constant>)
              terms.push_back(toml::table{{"type", "constant"}, {"value", t.value}});
            else if constexpr (std::is_same_v<T, LinearRamp>)
              terms.push_back(
                  toml::table{{"type", "ramp"}, {"value", t.value}, {"duration", t.duration}});
            else if constexpr (std::is_same_v<T, ExponentialRise>)
              terms.push_back(
                  toml::table{{"type", "exp_rise"}, {"value", t.value}, {"tau", t.tau}});
            else
              terms.push_back(toml::table{{"type", "growing_sine"},
                                          {"amplitude", t.amplitude},
                                          {"frequency", t.frequency},
                                          {"t_start", t.t_start},
                                          {"tau", t.tau},
                                          {"n_cycles", t.n_cycles}});
          },
          term);
    // Inline tables ({ type = ... }), as a case writes them.
    for (auto& t : terms)
      t.as_table()->is_inline(true);
    return terms;
  };
  toml::array fixed, vel, loads, cracks, probes;
  for (const FixedSpec& f : s.fixed)
    fixed.push_back(toml::table{{"set", f.set}, {"dofs", dofs_text(f.dofs)}});
  for (const VelocitySpec& v : s.velocities)
    vel.push_back(toml::table{{"set", v.set},
                              {"dofs", dofs_text(v.dofs)},
                              {"value", vec(v.value)},
                              {"function", function(v.scale)}});
  for (const LoadSpec& l : s.loads)
    loads.push_back(toml::table{{"name", l.name},
                                {"set", l.set},
                                {"force", vec(l.force)},
                                {"function", function(l.scale)}});
  for (std::size_t i = 0; i < s.precracks.size(); ++i) {
    const PrecrackSpec& p = s.precracks[i];
    cracks.push_back(toml::table{{"name", p.rect.name},
                                 {"origin", vec(c.cuts[i].origin)},
                                 {"edge1", vec(p.rect.edge1)},
                                 {"edge2", vec(p.rect.edge2)},
                                 {"nudge", p.nudge},
                                 {"nudged", c.cuts[i].nudged},
                                 {"bars_cut", static_cast<std::int64_t>(c.cuts[i].bars.size())}});
  }
  for (std::size_t i = 0; i < s.probes.size(); ++i) {
    const ProbeSpec& p = s.probes[i];
    toml::table t{{"name", p.name}};
    if (p.kind == ProbeSpec::Kind::BarForce) {
      t.insert("kind", "bar_force");
      t.insert("at", vec(p.at));
      t.insert("bar", static_cast<std::int64_t>(c.probe_bars[i]));
    } else if (p.kind == ProbeSpec::Kind::Reaction) {
      t.insert("kind", "reaction");
      t.insert("set", p.set);
      t.insert("component", std::string(1, static_cast<char>('x' + p.component)));
    } else {
      t.insert("kind", "load");
      t.insert("load", p.load);
    }
    probes.push_back(t);
  }
  if (!fixed.empty())
    root.insert("fixed", fixed);
  if (!vel.empty())
    root.insert("velocity", vel);
  if (!loads.empty())
    root.insert("load", loads);
  if (!cracks.empty())
    root.insert("precrack", cracks);
  const char* rule = s.step.rule == TimeStep::Rule::Given   ? "dt"
                     : s.step.rule == TimeStep::Rule::Paper ? "paper"
                                                            : "safety";
  root.insert("time", toml::table{{"end", s.end_time},
                                  {"rule", rule},
                                  {"safety", s.step.safety},
                                  {"courant", s.step.courant},
                                  {"dt", body.dt},
                                  {"damping", s.damping}});
  if (s.stop_displacement > 0)
    root["time"].as_table()->insert("stop_displacement", s.stop_displacement);
  root.insert("output",
              toml::table{{"energy_every", static_cast<std::int64_t>(s.output.energy_every)},
                          {"vtu_every", static_cast<std::int64_t>(s.output.vtu_every)},
                          {"vtu", s.output.vtu},
                          {"plots", s.output.plots}});
  if (!probes.empty())
    root.insert("probe", probes);
  {
    toml::table an{{"crack", s.analysis.crack}};
    if (s.analysis.min_branch_length > 0)
      an.insert("min_branch_length", s.analysis.min_branch_length);
    if (s.analysis.branch_fit_length > 0)
      an.insert("branch_fit_length", s.analysis.branch_fit_length);
    if (s.analysis.speed_window > 0)
      an.insert("speed_window", s.analysis.speed_window);
    an.insert("fatigue", s.analysis.fatigue);
    if (!s.analysis.fatigue_load.empty())
      an.insert("fatigue_load", s.analysis.fatigue_load);
    an.insert("fatigue_points", s.analysis.fatigue_points);
    an.insert("fatigue_window", s.analysis.fatigue_window);
    if (s.analysis.fatigue_band > 0)
      an.insert("fatigue_band", s.analysis.fatigue_band);
    if (s.analysis.fatigue_unstable_advance > 0)
      an.insert("fatigue_unstable_advance", s.analysis.fatigue_unstable_advance);
    if (s.analysis.fatigue_width > 0)
      an.insert("fatigue_width", s.analysis.fatigue_width);
    root.insert("analysis", an);
  }
  const DuctilitySummary& k = body.ductility;
  // c of the stiffest bars, as the paper's step rule takes it.
  const double c_bar = std::sqrt(body.ranges.E[1] / s.material.rho);
  root.insert("resolved",
              toml::table{{"nodes", static_cast<std::int64_t>(lat.num_nodes())},
                          {"bars", static_cast<std::int64_t>(lat.num_bars())},
                          {"steps", static_cast<std::int64_t>(std::ceil(s.end_time / body.dt))},
                          {"dt", body.dt},
                          {"dt_over_L_c", body.dt * c_bar / s.L},
                          {"dt_stable", body.stable.dt},
                          {"dt_stable_over_L_c", body.stable.dt * c_bar / s.L},
                          {"dt_proven_bound", body.stable.dt_bound},
                          {"K_r_normal_min", k.kr_min_normal},
                          {"K_r_normal_max", k.kr_max_normal},
                          {"K_r_diagonal_min", k.kr_min_diag},
                          {"K_r_diagonal_max", k.kr_max_diag},
                          {"L_cr", k.L_cr_min},
                          {"precracked_bars", static_cast<std::int64_t>(c.precracked.size())}});
  std::ostringstream os;
  os << "# The case as run: every default and derived value ([resolved]).\n" << root << "\n";
  return os.str();
}

int check_command(const std::string& path) {
  const BuiltCase c = build_case(path);
  for (const std::string& w : c.warnings)
    fmt::print(stderr, "ldem: warning: {}\n", w);
  fmt::print("{}", resolved_case_toml(c, body_numbers(*c.sim)));
  fmt::print(stderr, "{}: valid ({} nodes, {} bars, dt = {:.4g} s of a stable {:.4g} s)\n", path,
             c.sim->lattice().num_nodes(), c.sim->lattice().num_bars(), c.sim->dt(),
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

  fmt::print("{}: {} x {} x {} modules, {} free DOF of {}, {} broken bars left out\n", path,
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

// Makes the output folder ready, after the case has been validated: it must be new or empty
// (or `force`), and writable. Nothing is created or changed when this throws.
// Checks that `dir` can take a run's outputs (a folder that is empty, or --force), and with
// `create` makes it if it does not exist yet.
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

namespace {

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(fmt::format("{}: cannot read", path));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Where a run stands between steps: what the outputs need to continue.
struct RunState {
  std::string case_path; // absolute
  std::uint64_t case_hash = 0;
  std::uint64_t next = 0; // the next step to take
  std::vector<std::pair<double, std::string>> snapshots;
  std::uint64_t n_soft = 0, n_broken = 0;
  double max_balance = 0.0;
  std::uint64_t lengths[3] = {0, 0, 0}; // bytes of energy.csv, events.csv, probes.csv
};

// The run's state as a checkpoint's meta (io/checkpoint.hpp), and back.
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
  return st;
}

// The time-step loop of a run, from step st.next, writing into `dir` (the first process
// writes; in a distributed run every process steps its subdomain and takes part in each
// exchange).
// `fresh`: the output files start with their headers; otherwise they continue where the
// checkpoint left them.
int run_loop(BuiltCase& c, RunBody& body, const std::string& out_dir, RunState st, bool fresh,
             bool plots, std::uint64_t checkpoint_every, double checkpoint_seconds) {
  const CaseSpec& s = c.spec;
  const Lattice& lat = body.lattice();
  const bool writes = body.writes();
  const std::string dir = out_dir + "/";
  auto steps = static_cast<std::uint64_t>(std::ceil(s.end_time / body.dt() - 1e-9));
  const std::uint64_t every =
      s.output.energy_every ? s.output.energy_every : std::max<std::uint64_t>(1, steps / 500);
  const std::uint64_t vtu_every =
      s.output.vtu_every ? s.output.vtu_every : std::max<std::uint64_t>(1, steps / 20);

  auto open = [&](const char* name, int i) -> std::unique_ptr<OutputFile> {
    if (!writes)
      return nullptr;
    return fresh ? std::make_unique<OutputFile>(dir + name)
                 : std::make_unique<OutputFile>(dir + name, st.lengths[i]);
  };
  const auto energy = open("energy.csv", 0), events = open("events.csv", 1),
             probes = open("probes.csv", 2);
  if (fresh && writes) {
    energy->write("time,external_work,elastic,kinetic,damage_dissipated,damping_dissipated,"
                  "balance_error\n");
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
  const auto t0 = std::chrono::steady_clock::now();
  auto last_checkpoint = t0;
  const std::uint64_t first = st.next;
  std::uint64_t n = st.next;
  std::string blow_up, stopped_by;
  bool blew_up = false;
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
    if (look && n > first && checkpoint_seconds > 0) // the first process's clock decides
      save |=
          body.max_over_processes(writes && std::chrono::duration<double>(
                                                std::chrono::steady_clock::now() - last_checkpoint)
                                                    .count() > checkpoint_seconds) != 0;
    if (save) {
      save_checkpoint(n);
      last_checkpoint = std::chrono::steady_clock::now();
    }
    // Every 10 steps, a look for a numerical blow-up (a NaN, or displacements beyond any
    // physical scale): the run stops with the first bad node, keeping its outputs up to here
    // and its last checkpoint.
    if (n % 10 == 0) {
      const double limit =
          1e3 * lat.L() * static_cast<double>(std::max({lat.nx(), lat.ny(), lat.nz()}));
      const index_t bad = body.first_node_beyond(limit);
      if (bad < lat.num_nodes()) {
        blew_up = true;
        const Vec3 u = body.displacement(bad);
        if (writes) {
          const Vec3 x = lat.position(bad);
          blow_up = fmt::format("numerical blow-up detected at step {} (t = {:.6g} s): node {} "
                                "at ({:g}, {:g}, {:g}) m has displacement ({:g}, {:g}, {:g}) m. "
                                "Check the case's loads, velocities and material values; the "
                                "outputs are complete up to the last report before this step",
                                n, body.time(), bad, x.x, x.y, x.z, u.x, u.y, u.z);
        }
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
    if (report && writes) {
      probe_row();
      flush_events();
      const EnergyReport& r = body.last_report();
      energy->write(fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.6g}\n", r.time,
                                r.external_work, r.elastic, r.kinetic, r.damage_dissipated,
                                r.damping_dissipated, r.balance_error));
      if (r.external_work + r.initial > 1e-6 * (r.elastic + r.kinetic + r.damage_dissipated) &&
          n > 0)
        st.max_balance = std::max(st.max_balance, r.balance_error);
      if (std::chrono::steady_clock::now() - last_flush > std::chrono::seconds(1))
        flush_live();
      progress->update(n, r.time, st.n_broken + c.precracked.size(), r.balance_error, n == steps);
    }
  }
  if (signal)
    save_checkpoint(n);
  if (writes)
    flush_live(); // the last rows and snapshots, within the loop's time
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto [softened, broken] = body.softening_and_broken(); // the final state
  if (!writes) // the first process reports; the others end with its exit code
    return blew_up ? 3 : signal == SIGTERM ? 143 : signal ? 130 : 0;
  energy->commit();
  events->commit();
  probes->commit();
  const std::uint64_t done = n - first;
  const ProcessGrid grid = body.grid();
  write_file(
      dir + "summary.json",
      fmt::format("{{\n  \"case\": \"{}\",\n  \"title\": \"{}\",\n  \"nodes\": {},\n"
                  "  \"bars\": {},\n  \"steps\": {},\n  \"dt\": {:.9g},\n"
                  "  \"dt_stable\": {:.9g},\n  \"end_time\": {:.9g},\n  \"wall_s\": {:.4f},\n"
                  "  \"bar_updates_per_s\": {:.6g},\n  \"threads\": {},\n  \"processes\": {},\n"
                  "  \"process_grid\": [1, {}, {}],\n  \"bytes_per_module\": {:.1f},\n"
                  "  \"max_balance_error\": {:.6g},\n  \"softening_bars_at_end\": {},\n"
                  "  \"broken_bars_at_end\": {},\n  \"precracked_bars\": {},\n"
                  "  \"interrupted\": {},\n  \"stopped_by\": {},\n  \"analysis\": {{}}\n}}\n",
                  st.case_path, s.title, lat.num_nodes(), lat.num_bars(), n, body.dt(),
                  body.stable_step().dt, body.time(), wall,
                  static_cast<double>(lat.num_bars()) * static_cast<double>(done) / wall,
                  omp_get_max_threads(), process_count(), grid.py, grid.pz,
                  body.numbers().bytes_per_module, st.max_balance, softened, broken,
                  c.precracked.size(), signal ? "true" : "false",
                  stopped_by.empty() ? std::string("null") : "\"" + stopped_by + "\""));
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
  fmt::print(stderr, "ldem: done: {} steps in {:.1f} s, results in {}\n", done, wall, out_dir);
  return 0;
}

} // namespace

// From here on a Ctrl-C or SIGTERM only asks the run to stop at the next step boundary (with
// a checkpoint); before the first step that is step 0.
void catch_stop_signals() {
  g_interrupted = 0;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

namespace {

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

// run_loop, and in a distributed run an error on one process (an output that cannot be
// written, say) ends all of them: the others would wait for it at the next exchange.
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
        c = build_case(path, o.adjust, process_count() == 1);
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
  st.case_path = fs::absolute(path).string();
  if (writes) {
    for (const std::string& w : c.warnings)
      fmt::print(stderr, "ldem: warning: {}\n", w);
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(o.out_dir)) // --force: old snapshots go
      if (e.path().extension() == ".vtu" && e.path().filename().string().rfind("lattice_", 0) == 0)
        fs::remove(e.path());
    fs::remove_all(o.out_dir + "/checkpoint", ec);
    write_file(dir + "case.resolved.toml", resolved_case_toml(c, body->numbers()));
    const std::string text = read_all(path);
    st.case_hash = checkpoint::fnv1a(text.data(), text.size());
    if (process_count() > 1)
      fmt::print(stderr, "ldem: {}\n", describe_decomposition(*c.lattice, grid));
  }
  return guarded_loop([&] {
    if (body->numbers().per_bar)
      body->write_fields(dir + "fields.csv");
    return run_loop(c, *body, o.out_dir, st, true, o.plots,
                    o.checkpoint_every >= 0 ? static_cast<std::uint64_t>(o.checkpoint_every)
                                            : c.spec.output.checkpoint_every,
                    o.checkpoint_seconds >= 0 ? o.checkpoint_seconds
                                              : c.spec.output.checkpoint_seconds);
  });
}

int resume_command(const std::string& out_dir, int threads, bool plots, int grid_y, int grid_z) {
  catch_stop_signals();
  if (threads > 0)
    omp_set_num_threads(threads);
  const bool writes = process_rank() == 0;
  const std::string path = out_dir + "/checkpoint/state.ckpt";
  RunState st;
  BuiltCase c;
  // The first process reads the run's state from the checkpoint (written by any number of
  // processes) and checks its case file; every process builds the case (a distributed run its
  // subdomain) and loads its part of the body's state from the file.
  if (!agreed([&] {
        if (!writes)
          return;
        st = parse_run_state(checkpoint::read_header(path).meta);
        std::string text;
        try {
          text = read_all(st.case_path);
        } catch (const InputError&) {
          throw InputError(fmt::format("{}: the case file of this run is gone; a resume needs "
                                       "it unchanged",
                                       st.case_path));
        }
        if (checkpoint::fnv1a(text.data(), text.size()) != st.case_hash)
          throw InputError(fmt::format("{}: the case file changed since the checkpoint in {}; "
                                       "a resume needs it unchanged (start a new run instead)",
                                       st.case_path, out_dir));
      }))
    return 2;
  std::string case_path = st.case_path;
  broadcast_from_first(case_path);
  if (!agreed([&] { c = build_case(case_path, nullptr, process_count() == 1); }))
    return 2;
  const std::unique_ptr<RunBody> body = make_body(c, {grid_y, grid_z});
  if (!body)
    return 2;
  if (!agreed([&] { body->read_checkpoint(path); }))
    return 2;
  st.next = body->step_count(); // the checkpoint's next step, on every process
  if (writes)
    fmt::print(stderr, "ldem: resuming {} at step {} (t = {:.4g} s)\n", st.case_path, st.next,
               body->time());
  return guarded_loop([&] {
    return run_loop(c, *body, out_dir, st, false, plots, c.spec.output.checkpoint_every,
                    c.spec.output.checkpoint_seconds);
  });
}

int plot_command(const std::string& dir) {
  const std::string cmd = fmt::format("/usr/bin/python3 '{}' '{}'", LDEM_PLOT_SCRIPT, dir);
  const int rc = std::system(cmd.c_str());
  if (rc != 0) {
    fmt::print(stderr, "ldem: warning: plotting failed (needs /usr/bin/python3 with matplotlib: "
                       "apt-get install python3-matplotlib); the data files are complete\n");
    return 1;
  }
  return 0;
}

} // namespace ldem
