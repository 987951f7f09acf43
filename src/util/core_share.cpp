#include "util/core_share.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <omp.h>
#include <unistd.h>

namespace ldem {

std::vector<int> stepping_runs(const std::string& proc) {
  std::vector<int> runs;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(proc, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || !std::all_of(name.begin(), name.end(), ::isdigit))
      continue;
    // stat: "pid (comm) state ...": the command name, and the state (T, t stopped; Z, X ended).
    std::ifstream stat(entry.path() / "stat");
    std::string line;
    if (!std::getline(stat, line))
      continue; // (ended meanwhile)
    const std::size_t open = line.find('('), close = line.rfind(')');
    if (open == std::string::npos || close == std::string::npos || close + 2 >= line.size())
      continue;
    const char state = line[close + 2];
    if (line.compare(open + 1, close - open - 1, "ldem") != 0 ||
        std::string("TtZXx").find(state) != std::string::npos)
      continue;
    // cmdline: the arguments, each ended by a NUL; the command is the first after the program.
    std::ifstream cmd(entry.path() / "cmdline", std::ios::binary);
    const std::string args{std::istreambuf_iterator<char>(cmd), std::istreambuf_iterator<char>()};
    const std::size_t end = args.find('\0');
    if (end == std::string::npos)
      continue;
    const std::string command = args.substr(end + 1, args.find('\0', end + 1) - end - 1);
    if (command == "run" || command == "resume" || command == "bench" || command == "modes")
      runs.push_back(std::atoi(name.c_str()));
  }
  std::sort(runs.begin(), runs.end());
  return runs;
}

int core_share(int cores, const std::vector<int>& runs, int pid) {
  const auto at = std::lower_bound(runs.begin(), runs.end(), pid);
  const bool listed = at != runs.end() && *at == pid;
  const int n = static_cast<int>(runs.size()) + (listed ? 0 : 1);
  const int place = listed ? static_cast<int>(at - runs.begin()) : n - 1;
  return std::max(1, cores / n + (place < cores % n ? 1 : 0));
}

bool shares_cores(int threads_option) {
  const char* env = std::getenv("OMP_NUM_THREADS");
  return threads_option <= 0 && (env == nullptr || *env == '\0');
}

int current_core_share() {
  return core_share(omp_get_num_procs(), stepping_runs(), static_cast<int>(getpid()));
}

} // namespace ldem
