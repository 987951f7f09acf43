#include "analysis/fatigue.hpp"

#include "analysis/run_data.hpp"
#include "io/output.hpp"
#include "solver/time_function.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <sstream>

namespace ldem {

double tada_edge_crack_factor(double s) {
  if (!(s > 0.0 && s <= kTadaMaxRatio * (1.0 + 1e-12)))
    throw InputError(fmt::format(
        "single-edge-crack factor: a/b = {:g} is outside the range 0 < a/b <= {:g} where "
        "Tada's closed form is used (the crack is too long for a Paris characterisation)",
        s, kTadaMaxRatio));
  const double q = 0.5 * std::numbers::pi * s;
  const double c = 0.752 + 2.02 * s + 0.37 * std::pow(1.0 - std::sin(q), 3);
  return std::sqrt(std::tan(q) / q) * c / std::cos(q);
}

ParisFit fit_paris(const std::vector<double>& delta_K, const std::vector<double>& da_dN,
                   double confidence) {
  if (delta_K.size() != da_dN.size())
    throw InputError("Paris fit: Delta K and da/dN differ in length");
  if (!(confidence > 0.0 && confidence < 1.0))
    throw InputError(fmt::format("Paris fit: confidence must be in (0, 1), got {:g}", confidence));
  const std::size_t n = delta_K.size();
  if (n < 3)
    throw InputError(fmt::format("Paris fit: needs at least 3 points, got {}", n));
  std::vector<double> x(n), y(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!(delta_K[i] > 0.0) || !(da_dN[i] > 0.0))
      throw InputError(
          fmt::format("Paris fit: point {} has Delta K = {:g}, da/dN = {:g}; both must be positive",
                      i, delta_K[i], da_dN[i]));
    x[i] = std::log10(delta_K[i]);
    y[i] = std::log10(da_dN[i]);
  }
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double sxx = 0.0, sxy = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
    syy += (y[i] - my) * (y[i] - my);
  }
  if (!(sxx > 0.0))
    throw InputError("Paris fit: every point has the same Delta K; no line can be fitted");
  ParisFit f;
  f.points = n;
  f.confidence = confidence;
  f.m = sxy / sxx;
  f.log10_C = my - f.m * mx;
  f.C = std::pow(10.0, f.log10_C);
  double sse = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = y[i] - (f.log10_C + f.m * x[i]);
    sse += r * r;
  }
  f.r2 = syy > 0.0 ? 1.0 - sse / syy : 1.0;
  // Standard error of the slope, s_m^2 = SSE / ((n - 2) Sxx), and the Student t quantile
  // with n - 2 degrees of freedom.
  const double dof = static_cast<double>(n - 2);
  const double se = std::sqrt(sse / (dof * sxx));
  const boost::math::students_t dist(dof);
  const double t = boost::math::quantile(dist, 0.5 + 0.5 * confidence);
  f.m_low = f.m - t * se;
  f.m_high = f.m + t * se;
  return f;
}

std::vector<double> column_first_times(const std::vector<BarEvent>& events, const FrontOptions& o) {
  const auto columns = static_cast<std::size_t>(std::llround(o.x_end / o.L));
  std::vector<double> first(columns, std::numeric_limits<double>::quiet_NaN());
  for (const BarEvent& e : events) {
    if (std::abs(e.n - o.plane) > o.band)
      continue;
    // A bar centred exactly on a column boundary (a bar across the crack plane at x = i L)
    // belongs to the column it starts: i.
    const double c = std::floor(e.x / o.L + 1e-9);
    if (c < 0.0 || c >= static_cast<double>(columns))
      continue;
    double& f = first[static_cast<std::size_t>(c)];
    if (std::isnan(f) || e.t < f)
      f = e.t;
  }
  return first;
}

std::vector<FrontStep> damage_front(const std::vector<BarEvent>& events, const FrontOptions& o) {
  const std::vector<double> first = column_first_times(events, o);
  // The tip's column is the one the pre-crack ends in.
  const auto c0 = static_cast<std::size_t>(std::max(0.0, std::floor(o.tip / o.L + 1e-9)));
  std::vector<FrontStep> front;
  double t_reach = -std::numeric_limits<double>::infinity();
  for (std::size_t c = c0; c < first.size(); ++c) {
    if (std::isnan(first[c]))
      break;
    // The column counts once it and every column before it have been reached.
    t_reach = std::max(t_reach, first[c]);
    const double a = static_cast<double>(c + 1) * o.L;
    if (!front.empty() && front.back().t == t_reach)
      front.back().a = a;
    else
      front.push_back({t_reach, a});
  }
  return front;
}

double front_at(const std::vector<FrontStep>& front, double tip, double t) {
  double a = tip;
  for (const FrontStep& s : front) {
    if (s.t > t)
      break;
    a = std::max(a, s.a);
  }
  return a;
}

double CyclicLoad::range_at(double time) const {
  const double half = 0.5 / frequency;
  const auto lo = std::lower_bound(t.begin(), t.end(), time - half);
  const auto hi = std::upper_bound(t.begin(), t.end(), time + half);
  if (lo >= hi)
    return 0.0;
  const auto i0 = static_cast<std::size_t>(lo - t.begin());
  const auto i1 = static_cast<std::size_t>(hi - t.begin());
  const auto [mn, mx] = std::minmax_element(sigma.begin() + static_cast<std::ptrdiff_t>(i0),
                                            sigma.begin() + static_cast<std::ptrdiff_t>(i1));
  return *mx - *mn;
}

double CyclicLoad::cycles_at(double time) const {
  double J = 0.0;
  const auto at = std::lower_bound(row_t.begin(), row_t.end(), time);
  if (at != row_t.end())
    J = jumped[static_cast<std::size_t>(at - row_t.begin())];
  else if (!jumped.empty())
    J = jumped.back();
  return (time - t_constant) * frequency + J;
}

std::vector<BarEvent> first_damage(const std::vector<BarEvent>& softening,
                                   const std::vector<BarEvent>& broken) {
  std::vector<BarEvent> e = softening;
  e.insert(e.end(), broken.begin(), broken.end());
  return e;
}

FatigueAnalysis analyze_fatigue(const std::vector<BarEvent>& softening,
                                const std::vector<BarEvent>& broken, const FrontOptions& fo,
                                const CyclicLoad& load, const FatigueOptions& o, double t_end) {
  FatigueAnalysis r;
  r.t_end = t_end;
  r.front = damage_front(first_damage(softening, broken), fo);
  r.rupture_front = damage_front(broken, fo);
  const double period = 1.0 / load.frequency;
  auto N_of = [&](double t) { return load.cycles_at(t); };
  auto a_of = [&](double t) { return front_at(r.front, fo.tip, t); };
  r.a_at_constant = a_of(load.t_constant);

  // Onset of unstable failure: the first front step from which the front runs at least
  // `unstable_advance` within one load period.
  auto a_before = [&](double t) { return front_at(r.front, fo.tip, std::nextafter(t, -1e300)); };
  for (const FrontStep& s : r.front)
    if (a_of(s.t + period) - a_before(s.t) >= o.unstable_advance) {
      r.unstable_t = s.t;
      r.cycles_to_failure = N_of(s.t);
      break;
    }
  // Start of subcritical growth: the first time, once the load cycles, that the front moves
  // (the damage formed while the load first rises is the pre-crack's process zone).
  for (const FrontStep& s : r.front)
    if (s.t >= load.t_cycles && (!r.unstable_t || s.t < *r.unstable_t)) {
      r.subcritical_start_t = s.t;
      break;
    }

  // Representative points over the window where N >= 0, the growth is subcritical and the
  // front moves: from max(start, N = 0) to the unstable onset (or the end of the run).
  if (!r.subcritical_start_t) {
    r.note = "the front does not advance while the load cycles before any unstable failure";
    return r;
  }
  const double w0 =
      std::max(*r.subcritical_start_t, o.from_first_cycle ? load.t_cycles : load.t_constant);
  // The window ends at the unstable onset, or, in a run without one, at the front's last
  // advance (an arrested crack has no growth rate to measure after it).
  const char* where = o.from_first_cycle ? "while the load cycles" : "at constant amplitude";
  if (!r.unstable_t && (r.front.empty() || r.front.back().t <= w0)) {
    r.note = fmt::format("the front does not advance {} (its last advance: t = {:.6g} s, N = "
                         "{:.1f}); no growth rate to measure",
                         where, r.front.empty() ? 0.0 : r.front.back().t,
                         r.front.empty() ? 0.0 : N_of(r.front.back().t));
    return r;
  }
  // The front just before the unstable onset: the last point must not include the jump.
  const double w1_in = r.unstable_t ? std::nextafter(*r.unstable_t, -1e300) : r.front.back().t;
  if (!(w1_in > w0 + period) || o.points < 2) {
    r.note = fmt::format("the window of subcritical growth {} is shorter than one cycle "
                         "({:.6g} s to {:.6g} s)",
                         where, w0, w1_in);
    return r;
  }
  if (o.fit_elastic)
    for (const BarEvent& e : softening)
      if (e.t >= w0 && std::abs(e.n - fo.plane) <= fo.band &&
          (!r.first_softening_t || e.t < *r.first_softening_t))
        r.first_softening_t = e.t;
  std::vector<double> rep_t;
  if (o.secant) {
    // The front's own steps within the window. At a step the tip enters the column whose far
    // edge is the new front, so between two steps it moves from a_i - L to a_{i+1} - L.
    for (const FrontStep& s : r.front)
      if (s.t >= w0 && s.t <= w1_in)
        rep_t.push_back(s.t);
  } else {
    for (std::size_t i = 0; i < o.points; ++i)
      rep_t.push_back(w0 +
                      (w1_in - w0) * static_cast<double>(i) / static_cast<double>(o.points - 1));
  }
  for (const double t : rep_t) {
    r.rep_N.push_back(N_of(t));
    r.rep_a.push_back(a_of(t));
  }
  std::vector<double> dK, rate;
  for (std::size_t i = 0; i + 1 < rep_t.size(); ++i) {
    FatigueRow row{};
    const double dN = r.rep_N[i + 1] - r.rep_N[i];
    row.N = 0.5 * (r.rep_N[i] + r.rep_N[i + 1]);
    row.a = 0.5 * (r.rep_a[i] + r.rep_a[i + 1]) - (o.secant ? fo.L : 0.0);
    row.da_dN = (r.rep_a[i + 1] - r.rep_a[i]) / dN;
    const double s = row.a / o.b;
    const double t_mid = 0.5 * (rep_t[i] + rep_t[i + 1]); // (N is not linear in t with jumps)
    row.delta_K =
        s > 0.0 && s <= kTadaMaxRatio * (1.0 + 1e-12)
            ? load.range_at(t_mid) * std::sqrt(std::numbers::pi * row.a) * tada_edge_crack_factor(s)
            : std::numeric_limits<double>::quiet_NaN();
    row.in_fit = row.da_dN > 0.0 && std::isfinite(row.delta_K) && row.delta_K > 0.0 &&
                 row.a - fo.tip >= o.fit_after &&
                 !(r.first_softening_t && rep_t[i + 1] > *r.first_softening_t);
    if (row.in_fit) {
      dK.push_back(row.delta_K);
      rate.push_back(row.da_dN);
    }
    r.rows.push_back(row);
  }
  const std::size_t outside = static_cast<std::size_t>(std::count_if(
      r.rows.begin(), r.rows.end(), [](const FatigueRow& w) { return !std::isfinite(w.delta_K); }));
  const std::size_t still =
      static_cast<std::size_t>(std::count_if(r.rows.begin(), r.rows.end(), [](const FatigueRow& w) {
        return std::isfinite(w.delta_K) && !(w.da_dN > 0.0);
      }));
  const std::size_t near = static_cast<std::size_t>(
      std::count_if(r.rows.begin(), r.rows.end(), [&](const FatigueRow& w) {
        return std::isfinite(w.delta_K) && w.da_dN > 0.0 && w.a - fo.tip < o.fit_after;
      }));
  const std::size_t yielding = static_cast<std::size_t>(
      std::count_if(r.rows.begin(), r.rows.end(), [&](const FatigueRow& w) {
        return std::isfinite(w.delta_K) && w.da_dN > 0.0 && w.a - fo.tip >= o.fit_after &&
               !w.in_fit;
      }));
  std::string why;
  if (yielding)
    why += fmt::format("{} interval(s) after the first softening near the crack (t = {:.6g} s, "
                       "N = {:.1f}) left out; ",
                       yielding, *r.first_softening_t, N_of(*r.first_softening_t));
  if (near)
    why += fmt::format("{} interval(s) within fatigue_fit_after = {:g} m of the pre-crack's tip "
                       "left out; ",
                       near, o.fit_after);
  if (outside)
    why += fmt::format("{} interval(s) with a/b > {:g} (beyond Tada's range) left out; ", outside,
                       kTadaMaxRatio);
  if (still)
    why += fmt::format("{} interval(s) without front advance (da/dN = 0) left out; ", still);
  std::set<double> distinct(dK.begin(), dK.end());
  if (dK.size() >= 3 && distinct.size() >= 2) {
    r.paris = fit_paris(dK, rate, o.confidence);
  } else {
    why += fmt::format("{} usable interval(s): no Paris fit (needs 3)", dK.size());
  }
  r.note = why;
  return r;
}

} // namespace ldem

namespace ldem {

// A traction is the remote stress itself; a force per node is spread over the section.
double load_remote_stress(const RunGeometry& rg, const toml::table& load) {
  const toml::table& c = rg.resolved;
  const std::string& file = rg.case_file;
  const std::string name = load["name"].value_or(std::string());
  const std::string set = load["set"].value_or(std::string());
  // A total is spread over its area (a traction of total / area).
  const bool total = load.contains("total");
  const bool traction = total || load.contains("traction");
  const char* key = total ? "total" : traction ? "traction" : "force";
  std::array<double, 3> force{};
  for (std::size_t k = 0; k < 3; ++k)
    force[k] = resolved_number(load[key][k], file, std::string("load.") + key);
  const double magnitude =
      std::sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
  double sigma_unit = magnitude;
  if (total)
    sigma_unit = magnitude / resolved_number(load["area"], file, "load.area");
  if (!traction) {
    double nodes = 0.0;
    if (const auto* sets = c["node_set"].as_array())
      for (const toml::node& n : *sets)
        if (const toml::table* s = n.as_table(); s && (*s)["name"].value_or(std::string()) == set)
          nodes = (*s)["nodes_selected"].value_or(0.0);
    if (!(nodes > 0.0))
      throw InputError(
          fmt::format("{}: load \"{}\": its set \"{}\" has no nodes_selected", file, name, set));
    const auto axis = static_cast<std::size_t>(
        std::max_element(force.begin(), force.end(),
                         [](double p, double q) { return std::abs(p) < std::abs(q); }) -
        force.begin());
    double section = 1.0;
    for (std::size_t k = 0; k < 3; ++k)
      if (k != axis)
        section *= rg.extent[k];
    sigma_unit = magnitude * nodes / section;
  }
  return sigma_unit;
}

namespace {

// The remote stress of a load (load_remote_stress) over time.
CyclicLoad read_cyclic_load(const RunGeometry& rg, const std::string& wanted, double t_end) {
  const toml::table& c = rg.resolved;
  const std::string& file = rg.case_file;
  const auto* loads = c["load"].as_array();
  if (!loads || loads->empty())
    throw InputError(fmt::format("{}: the fatigue analysis needs a cyclic [[load]]; the case has "
                                 "none",
                                 file));
  const toml::table* chosen = nullptr;
  const toml::table* sine = nullptr;
  for (const toml::node& n : *loads) {
    const toml::table* l = n.as_table();
    if (!l)
      continue;
    const std::string name = (*l)["name"].value_or(std::string());
    const toml::array* f = (*l)["function"].as_array();
    const toml::table* s = nullptr;
    if (f)
      for (const toml::node& term : *f)
        if (const toml::table* tt = term.as_table();
            tt && (*tt)["type"].value_or(std::string()) == "growing_sine")
          s = tt;
    if (wanted.empty() ? s != nullptr : name == wanted) {
      chosen = l;
      sine = s;
      break;
    }
  }
  if (!chosen)
    throw InputError(
        wanted.empty()
            ? fmt::format("{}: the fatigue analysis needs a [[load]] whose function has a "
                          "\"growing_sine\" term; the case has none",
                          file)
            : fmt::format("{}: analysis.fatigue_load: no [[load]] named \"{}\"", file, wanted));
  const std::string name = (*chosen)["name"].value_or(std::string());
  if (!sine)
    throw InputError(fmt::format("{}: analysis.fatigue_load: the load \"{}\" has no "
                                 "\"growing_sine\" term, so it has no cycles to count",
                                 file, name));
  const double sigma_unit = load_remote_stress(rg, *chosen);

  std::vector<TimeTerm> terms;
  for (const toml::node& term : *(*chosen)["function"].as_array()) {
    const toml::node_view<const toml::node> v{term};
    const std::string type = v["type"].value_or(std::string());
    const double value = v["value"].value_or(1.0);
    if (type == "constant")
      terms.emplace_back(Constant{value});
    else if (type == "ramp")
      terms.emplace_back(LinearRamp{value, resolved_number(v["duration"], file, "duration")});
    else if (type == "exp_rise")
      terms.emplace_back(ExponentialRise{value, resolved_number(v["tau"], file, "tau")});
    else
      terms.emplace_back(GrowingSine{
          resolved_number(v["amplitude"], file, "amplitude"),
          resolved_number(v["frequency"], file, "frequency"), v["t_start"].value_or(0.0),
          resolved_number(v["tau"], file, "tau"), v["n_cycles"].value_or(0.0)});
  }
  const TimeFunction fn(terms);
  CyclicLoad cl;
  const auto& gs = std::get<GrowingSine>(terms[static_cast<std::size_t>(
      std::find_if(terms.begin(), terms.end(),
                   [](const TimeTerm& x) { return std::holds_alternative<GrowingSine>(x); }) -
      terms.begin())]);
  cl.frequency = gs.frequency;
  cl.t_cycles = gs.t_start;
  cl.t_constant = gs.t_start + gs.n_cycles / gs.frequency;
  // 64 samples per period resolve a cycle's extremes to 0.12 % of its amplitude.
  const double h = 1.0 / (64.0 * cl.frequency);
  // To the run's end, and at least two periods into the constant amplitude (its range).
  const double t_last = std::max(t_end, cl.t_constant) + 2.0 / cl.frequency;
  const auto samples = static_cast<std::size_t>(std::ceil(t_last / h)) + 1;
  cl.t.reserve(samples);
  cl.sigma.reserve(samples);
  for (std::size_t i = 0; i < samples; ++i) {
    const double t = static_cast<double>(i) * h;
    cl.t.push_back(t);
    cl.sigma.push_back(sigma_unit * fn(t));
  }
  return cl;
}

// Events with x measured from `border` along the crack.
std::vector<BarEvent> to_bar_events(const std::vector<CrackPoint>& p, double border) {
  std::vector<BarEvent> e;
  e.reserve(p.size());
  for (const CrackPoint& q : p)
    e.push_back({q.t, q.a - border, q.n});
  return e;
}

nlohmann::ordered_json opt_json(const std::optional<double>& v) {
  return v ? nlohmann::ordered_json(*v) : nlohmann::ordered_json(nullptr);
}

} // namespace

std::string fatigue_report(const FatigueAnalysis& r) {
  std::string s;
  if (r.subcritical_start_t)
    s += fmt::format("subcritical growth from t/tmax = {:.3f}", *r.subcritical_start_t / r.t_end);
  else
    s += "no growth while the load cycles";
  if (r.unstable_t)
    s += fmt::format(", unstable failure at t/tmax = {:.3f} after {:.1f} cycles at constant "
                     "amplitude",
                     *r.unstable_t / r.t_end, *r.cycles_to_failure);
  else
    s += ", no unstable failure in the run";
  if (r.paris)
    s += fmt::format("\nParis: da/dN = {:.4g} DK^{:.4g} (Pa, m), R^2 = {:.3f}, m in [{:.3g}, "
                     "{:.3g}] ({:.0f} %, {} points)",
                     r.paris->C, r.paris->m, r.paris->r2, r.paris->m_low, r.paris->m_high,
                     100.0 * r.paris->confidence, r.paris->points);
  if (!r.note.empty())
    s += "\nnote: " + r.note;
  return s;
}

namespace {
// energy.csv's row times and jumped_cycles column into `load`, when the run jumped cycles.
void read_jumped_cycles(const std::string& path, CyclicLoad& load) {
  std::ifstream in(path);
  std::string line;
  if (!std::getline(in, line) || !line.ends_with(",jumped_cycles"))
    return;
  while (std::getline(in, line)) {
    if (line.empty())
      continue;
    try {
      load.row_t.push_back(std::stod(line.substr(0, line.find(','))));
      load.jumped.push_back(std::stod(line.substr(line.rfind(',') + 1)));
    } catch (const std::exception&) {
      throw InputError(fmt::format("{}: expected numbers, got the row \"{}\"", path, line));
    }
  }
}
} // namespace

FatigueAnalysis analyze_fatigue_dir(const std::string& dir, const std::string& window_override,
                                    const std::string& rate_override) {
  const RunGeometry rg = read_run_geometry(dir, "fatigue analysis");
  const toml::table& c = rg.resolved;
  const auto* an = c["analysis"].as_table();
  auto opt = [&](const char* key, double fallback) { return analysis_number(rg, key, fallback); };
  const double t_end = read_summary(dir).value("end_time", 0.0);
  if (!(t_end > 0.0))
    throw InputError(
        fmt::format("{}/summary.json: end_time: expected a positive time, got {:g}", dir, t_end));

  // x runs from the border the pre-crack starts at (the paper's a): the low one along its axis.
  const CrackGeometry& g = rg.crack;
  if (std::abs(g.mouth_a - g.a_lo) > std::abs(g.a_hi - g.mouth_a))
    throw InputError(fmt::format("{}: the fatigue analysis measures an edge crack from the low "
                                 "border along {}; this pre-crack starts at the high one",
                                 rg.case_file, "xyz"[rg.along]));
  const double width = g.a_hi - g.a_lo;
  FrontOptions fo;
  fo.L = rg.L;
  fo.tip = g.tip_a - g.a_lo;
  fo.plane = g.line_n;
  fo.band = opt("fatigue_band", 0.25 * (g.n_hi - g.n_lo));
  fo.x_end = width;
  FatigueOptions o;
  o.b = opt("fatigue_width", width);
  o.points = static_cast<std::size_t>(opt("fatigue_points", 10.0));
  o.unstable_advance = opt("fatigue_unstable_advance", 0.1 * width);
  // A choice between two words: the command line's, else the case's, else the first.
  auto choice = [&](const std::string& given, const char* key, const char* first,
                    const char* second) {
    const std::string v = !given.empty() ? given
                          : an           ? (*an)[key].value_or(std::string(first))
                                         : std::string(first);
    if (v != first && v != second)
      throw InputError(
          fmt::format("{}: expected \"{}\" or \"{}\", got \"{}\"", key, first, second, v));
    return v;
  };
  const std::string window = choice(window_override, "fatigue_window", "constant", "cycles");
  o.from_first_cycle = window == "cycles";
  const std::string rate_method = choice(rate_override, "fatigue_rate", "points", "secant");
  o.secant = rate_method == "secant";
  o.fit_after = opt("fatigue_fit_after", 0.0);
  o.fit_elastic = an && (*an)["fatigue_fit_elastic"].value_or(false);
  const std::string wanted = an ? (*an)["fatigue_load"].value_or(std::string()) : std::string();
  CyclicLoad load = read_cyclic_load(rg, wanted, t_end);
  read_jumped_cycles(dir + "/energy.csv", load);

  const auto softening = to_bar_events(read_bar_events(dir, rg, "softening"), g.a_lo);
  const auto broken = to_bar_events(read_bar_events(dir, rg, "broken"), g.a_lo);
  FatigueAnalysis r = analyze_fatigue(softening, broken, fo, load, o, t_end);

  std::string rows = "N,a,da_dN,delta_K,in_fit\n";
  for (const FatigueRow& w : r.rows)
    rows += fmt::format("{:.6g},{:.9g},{:.6g},{:.6g},{:d}\n", w.N, w.a, w.da_dN, w.delta_K,
                        w.in_fit ? 1 : 0);
  write_file(dir + "/fatigue.csv", rows);
  // The fronts and each column's first times, for the pictures.
  const std::vector<double> first_p = column_first_times(first_damage(softening, broken), fo);
  const std::vector<double> first_r = column_first_times(broken, fo);
  std::string cols = "x,first_damage_t,first_broken_t\n";
  for (std::size_t i = 0; i < first_p.size(); ++i)
    cols += fmt::format("{:.9g},{:.9g},{:.9g}\n", (static_cast<double>(i) + 0.5) * fo.L, first_p[i],
                        first_r[i]);
  write_file(dir + "/fatigue_columns.csv", cols);
  std::string fr = "t,N,a\n";
  for (const FrontStep& s : r.front)
    fr += fmt::format("{:.9g},{:.6g},{:.9g}\n", s.t, load.cycles_at(s.t), s.a);
  write_file(dir + "/fatigue_front.csv", fr);

  nlohmann::ordered_json j;
  j["paris_C"] = r.paris ? nlohmann::ordered_json(r.paris->C) : nlohmann::ordered_json(nullptr);
  j["paris_m"] = r.paris ? nlohmann::ordered_json(r.paris->m) : nlohmann::ordered_json(nullptr);
  j["paris_r2"] = r.paris ? nlohmann::ordered_json(r.paris->r2) : nlohmann::ordered_json(nullptr);
  j["paris_m_interval"] = r.paris ? nlohmann::ordered_json::array({r.paris->m_low, r.paris->m_high})
                                  : nlohmann::ordered_json(nullptr);
  j["paris_confidence"] = o.confidence;
  j["paris_points"] = r.paris ? r.paris->points : 0;
  j["subcritical_start_t_over_tmax"] = r.subcritical_start_t
                                           ? nlohmann::ordered_json(*r.subcritical_start_t / t_end)
                                           : nlohmann::ordered_json(nullptr);
  j["unstable_t_over_tmax"] = r.unstable_t ? nlohmann::ordered_json(*r.unstable_t / t_end)
                                           : nlohmann::ordered_json(nullptr);
  j["cycles_to_failure"] = opt_json(r.cycles_to_failure);
  j["tmax_s"] = t_end;
  j["jumped_cycles"] = load.jumped.empty() ? 0.0 : load.jumped.back();
  j["load_frequency_hz"] = load.frequency;
  j["constant_amplitude_from_s"] = load.t_constant;
  j["stress_range_constant_pa"] = load.range_at(load.t_constant + 0.5 / load.frequency);
  j["precrack_length_m"] = fo.tip;
  j["front_at_constant_amplitude_m"] = r.a_at_constant;
  j["final_front_m"] = r.front.empty() ? fo.tip : r.front.back().a;
  j["width_b_m"] = o.b;
  j["window"] = window;
  j["rate"] = rate_method;
  j["fit_after_m"] = o.fit_after;
  j["fit_elastic"] = o.fit_elastic;
  j["first_softening_in_window_t_s"] = opt_json(r.first_softening_t);
  j["representative_points"] = o.secant ? r.rep_N.size() : o.points;
  j["band_m"] = fo.band;
  j["unstable_advance_m"] = o.unstable_advance;
  j["note"] = r.note;
  update_summary(dir, "fatigue", j);
  return r;
}

} // namespace ldem
