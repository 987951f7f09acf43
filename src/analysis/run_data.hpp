// What the analyses read from and write to an output folder: the resolved case, the pre-crack
// and the analysis plane, the bar events, and summary.json.
#pragma once

#include "analysis/crack.hpp"

#include <array>
#include <nlohmann/json.hpp>
#include <string>
#include <toml++/toml.h>
#include <vector>

namespace ldem {

struct RunGeometry {
  std::string case_file; // DIR/case.resolved.toml
  toml::table resolved;  // its contents
  double L = 0.0;
  std::array<double, 3> extent{}; // the body's size per axis [m]
  int along = 0, normal = 2, out = 1; // axes: along the pre-crack, across it, projected out
  CrackGeometry crack;                // the first pre-crack in the analysis plane
};

// Reads DIR/case.resolved.toml and finds the analysis plane and the first pre-crack; `what`
// names the analysis for the message when the case has no pre-crack.
RunGeometry read_run_geometry(const std::string& dir, const std::string& what);

// Events of one kind ("softening" or "broken") from DIR/events.csv, projected onto the
// analysis plane (a: along the pre-crack, n: across it).
std::vector<CrackPoint> read_bar_events(const std::string& dir, const RunGeometry& g,
                                        const std::string& kind);

// A number of the case's [analysis] table, or `fallback` where the case leaves it out.
double analysis_number(const RunGeometry& g, const char* key, double fallback);

// A number of the resolved case; throws InputError naming the file and key if missing.
double resolved_number(const toml::node_view<const toml::node>& v, const std::string& file,
                       const std::string& key);

// DIR/summary.json; throws InputError naming it if it is missing or not JSON.
nlohmann::ordered_json read_summary(const std::string& dir);

// Replaces `analysis.<key>` in DIR/summary.json, keeping everything else.
void update_summary(const std::string& dir, const std::string& key,
                    const nlohmann::ordered_json& value);

std::string read_text(const std::string& path, const std::string& what);

} // namespace ldem
