#include "analysis/run_data.hpp"

#include "io/output.hpp"
#include "util/error.hpp"
#include "util/text_file.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <sstream>

namespace ldem {

std::string read_text(const std::string& path, const std::string& what) {
  try {
    return read_text_file(path, what);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (is the folder an ldem output folder?)");
  }
}

double resolved_number(const toml::node_view<const toml::node>& v, const std::string& file,
                       const std::string& key) {
  if (const auto x = v.value<double>())
    return *x;
  throw InputError(fmt::format("{}: {}: expected a number, got none", file, key));
}


RunGeometry read_run_geometry(const std::string& dir, const std::string& what) {
  RunGeometry r;
  r.case_file = dir + "/case.resolved.toml";
  const std::string& case_file = r.case_file;
  toml::table& t = r.resolved;
  try {
    t = toml::parse(read_text(case_file, "the resolved case"), case_file);
  } catch (const toml::parse_error& e) {
    throw InputError(fmt::format("{}: not a readable resolved case: {}", case_file,
                                 e.description()));
  }
  const toml::table& c = t;
  const double L = resolved_number(c["lattice"]["L"], case_file, "lattice.L");
  double extent[3];
  for (int k = 0; k < 3; ++k)
    extent[k] = resolved_number(c["lattice"]["modules"][static_cast<std::size_t>(k)], case_file,
                    "lattice.modules") *
                L;
  const auto* cracks = c["precrack"].as_array();
  if (!cracks || cracks->empty())
    throw InputError(fmt::format("{}: the {} measures the crack from a pre-crack, and this "
                                 "case has no [[precrack]]",
                                 case_file, what));
  const toml::node_view<const toml::node> pc_view{cracks->front()};
  auto vec = [&](const char* key) {
    std::array<double, 3> v{};
    for (int k = 0; k < 3; ++k)
      v[static_cast<std::size_t>(k)] =
          resolved_number(pc_view[key][static_cast<std::size_t>(k)], case_file, std::string("precrack.") + key);
    return v;
  };
  const auto origin = vec("origin"), e1 = vec("edge1"), e2 = vec("edge2");

  // The analysis plane: the plane-strain axis (or the thinnest one) is projected out.
  const std::string ps = c["lattice"]["plane_strain"].value_or(std::string("none"));
  int out = ps == "x" ? 0 : ps == "y" ? 1 : ps == "z" ? 2 : -1;
  if (out < 0)
    out = static_cast<int>(std::min_element(extent, extent + 3) - extent);
  auto inplane = [&](const std::array<double, 3>& e) {
    double s = 0;
    for (int k = 0; k < 3; ++k)
      if (k != out)
        s += e[static_cast<std::size_t>(k)] * e[static_cast<std::size_t>(k)];
    return std::sqrt(s);
  };
  const auto& edge = inplane(e1) >= inplane(e2) ? e1 : e2;
  int along = -1;
  for (int k = 0; k < 3; ++k)
    if (k != out && (along < 0 || std::abs(edge[static_cast<std::size_t>(k)]) >
                                      std::abs(edge[static_cast<std::size_t>(along)])))
      along = k;
  const int normal = 3 - out - along;
  const auto A = static_cast<std::size_t>(along), N = static_cast<std::size_t>(normal);

  CrackGeometry g;
  g.L = L;
  g.a_lo = 0.0;
  g.a_hi = extent[along];
  g.n_lo = 0.0;
  g.n_hi = extent[normal];
  const double end0 = origin[A], end1 = origin[A] + edge[A];
  // The mouth is the end nearer a border of the body; the tip the other one.
  auto border_gap = [&](double a) { return std::min(std::abs(a - g.a_lo), std::abs(g.a_hi - a)); };
  const bool first_is_mouth = border_gap(end0) <= border_gap(end1);
  g.mouth_a = first_is_mouth ? end0 : end1;
  g.tip_a = first_is_mouth ? end1 : end0;
  g.line_n = origin[N] + 0.5 * (e1[N] + e2[N]);

  r.L = L;
  for (int k = 0; k < 3; ++k)
    r.extent[static_cast<std::size_t>(k)] = extent[k];
  r.along = along;
  r.normal = normal;
  r.out = out;
  r.crack = g;
  return r;
}

std::vector<CrackPoint> read_bar_events(const std::string& dir, const RunGeometry& g,
                                        const std::string& kind) {
  const int along = g.along, normal = g.normal;
  const std::string events_file = dir + "/events.csv";
  std::istringstream ev(read_text(events_file, "the events"));
  std::string line;
  std::getline(ev, line);
  if (line.rfind("bar,event,time,x,y,z", 0) != 0)
    throw InputError(fmt::format("{}:1: expected the header bar,event,time,x,y,z, got '{}'",
                                 events_file, line));
  std::vector<CrackPoint> events;
  std::size_t row = 1;
  while (std::getline(ev, line)) {
    ++row;
    if (line.empty())
      continue;
    std::array<std::string, 6> f;
    std::istringstream ls(line);
    for (auto& x : f)
      std::getline(ls, x, ',');
    if (f[1] != kind)
      continue;
    try {
      const double p[3] = {std::stod(f[3]), std::stod(f[4]), std::stod(f[5])};
      events.push_back({std::stod(f[2]), p[along], p[normal]});
    } catch (const std::exception&) {
      throw InputError(fmt::format("{}:{}: expected bar,event,time,x,y,z numbers, got '{}'",
                                   events_file, row, line));
    }
  }

  return events;
}

double analysis_number(const RunGeometry& g, const char* key, double fallback) {
  if (const auto* an = g.resolved["analysis"].as_table())
    if (const auto v = (*an)[key].value<double>())
      return *v;
  return fallback;
}

nlohmann::ordered_json read_summary(const std::string& dir) {
  const std::string summary_file = dir + "/summary.json";
  try {
    return nlohmann::ordered_json::parse(read_text(summary_file, "the run's summary"));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: not readable as JSON: {}", summary_file, e.what()));
  }
}

void update_summary(const std::string& dir, const std::string& key,
                    const nlohmann::ordered_json& value) {
  const std::string summary_file = dir + "/summary.json";
  nlohmann::ordered_json summary = read_summary(dir);
  if (!summary.contains("analysis") || !summary["analysis"].is_object())
    summary["analysis"] = nlohmann::ordered_json::object();
  summary["analysis"][key] = value;
  write_file(summary_file, summary.dump(2) + "\n");
}

} // namespace ldem
