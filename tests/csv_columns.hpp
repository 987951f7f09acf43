// A run's CSV log (energy.csv, probes.csv) read into columns by their names.
#pragma once

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace ldem::testing {

inline std::map<std::string, std::vector<double>> csv_columns(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  {
    std::istringstream ls(line);
    for (std::string x; std::getline(ls, x, ',');)
      names.push_back(x);
  }
  std::map<std::string, std::vector<double>> columns;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::size_t i = 0;
    for (std::string x; std::getline(ls, x, ','); ++i)
      columns[names.at(i)].push_back(std::stod(x));
  }
  return columns;
}

} // namespace ldem::testing
