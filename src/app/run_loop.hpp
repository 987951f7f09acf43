// The time-step loop of `ldem run` and `ldem resume` (commands.cpp): where a run stands
// between steps, its stop signals, and the loop that writes its outputs and checkpoints.
#pragma once

#include "app/case_run.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace ldem {

class RunBody;

// Where a run stands between steps: what the outputs need to continue.
struct RunState {
  std::string case_path; // absolute
  std::uint64_t case_hash = 0;
  std::uint64_t next = 0; // the next step to take
  std::vector<std::pair<double, std::string>> snapshots;
  std::uint64_t n_soft = 0, n_broken = 0;
  double max_balance = 0.0;
  std::uint64_t lengths[3] = {0, 0, 0}; // bytes of energy.csv, events.csv, probes.csv
  // What proves a checkpoint belongs to the folder it is in: the hash of case.resolved.toml as
  // the run wrote it, of the logs' first `lengths` bytes, and each snapshot's size.
  std::uint64_t resolved_hash = 0;
  std::uint64_t log_hashes[3] = {0, 0, 0};
  std::vector<std::uint64_t> snapshot_bytes;
  // The options the run was started with, which its resume keeps (the thread and process
  // counts change no output): plots at the end, checkpoints every so many steps and seconds.
  bool plots = true;
  std::uint64_t checkpoint_every = 0;
  double checkpoint_seconds = 0.0;
  // Cycle jumping: the cycles jumped so far, and the time at which the resolved window started
  // (negative: none yet).
  double jumped_cycles = 0.0;
  double window_start = -1.0;
  // The time the run goes to (0: the case's time.end; `ldem resume --end` sets it) and the
  // steps between its rows and between its snapshots, fixed when it starts (its case may give
  // 0: a number of rows over its first end), so that a run continued to a later end writes
  // what one run to that end with those intervals would.
  double end_time = 0.0;
  std::uint64_t energy_every = 0, vtu_every = 0;
  // Each resume that changed the run (`ldem resume --end`, `--case`): the step it resumed at,
  // the end it ran to, and the case file it went on with ("" if the same). summary.json lists
  // them.
  struct Continuation {
    std::uint64_t step = 0;
    double end_time = 0.0;
    std::string case_path;
  };
  std::vector<Continuation> continued;
  // Set by a resume that changed the case: the run writes a checkpoint before its first step,
  // so that the folder (its new case.resolved.toml) and its checkpoint agree from the start.
  bool case_changed = false;
};

// The logs of a run, in the order of RunState::lengths.
inline constexpr const char* kLogs[3] = {"energy.csv", "events.csv", "probes.csv"};

// Throws InputError naming the file unless the folder `out_dir` holds what the checkpoint's run
// state `st` recorded: case.resolved.toml unchanged, each log beginning with the bytes the
// checkpoint counted, each snapshot listed with its size. `ldem resume` calls it before it
// changes anything in the folder.
void check_folder_matches(const std::string& out_dir, const RunState& st);

// The steps of a run to `end_time` at dt: the last one's start is reported as the end.
std::uint64_t run_steps(double end_time, double dt);

// The run's state as a checkpoint's meta (io/checkpoint.hpp), and back.
std::string run_state_bytes(const RunState& st);
RunState parse_run_state(const std::string& meta);

// From here on a Ctrl-C or SIGTERM only asks the run to stop at the next step boundary (with
// a checkpoint); before the first step that is step 0.
void catch_stop_signals();

// The time-step loop of a run, from step st.next, writing into `out_dir` (the first process
// writes; in a distributed run every process steps its subdomain and takes part in each
// exchange). `fresh`: the output files start with their headers; otherwise they continue
// where the checkpoint left them. `share_cores`: the run takes its share of the machine's cores
// (util/core_share.hpp), looked at again about once a second. Returns the run's exit code.
int run_loop(BuiltCase& c, RunBody& body, const std::string& out_dir, RunState st, bool fresh,
             bool plots, std::uint64_t checkpoint_every, double checkpoint_seconds,
             bool share_cores = false);

// run_loop, and in a distributed run an error on one process (an output that cannot be
// written, say) ends all of them: the others would wait for it at the next exchange.
int guarded_loop(const std::function<int()>& loop);

} // namespace ldem
