// The ldem command line.
#include "app/bench.hpp"
#include "util/error.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <iostream>

namespace {
constexpr const char* kVersion = "0.1.0";
}

int main(int argc, char** argv) {
  CLI::App app{"ldem: crack propagation in quasi-brittle materials by the Lattice Discrete "
               "Element Method (Riera's cubic truss lattice, explicit dynamics, bilinear "
               "softening bars, full energy balance)",
               "ldem"};
  app.set_version_flag("--version", std::string("ldem ") + kVersion);
  app.require_subcommand(0, 1);

  ldem::BenchOptions bench;
  std::vector<unsigned> modules{64, 64, 64};
  auto* cmd_bench = app.add_subcommand(
      "bench", "Time elastic dynamics of a free 3-D lattice (small imposed strain rate); the last "
               "line reports bar updates per second over the time-step loop");
  cmd_bench->add_option("--modules", modules, "Modules along x, y, z")
      ->expected(3)
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd_bench->add_option("--steps", bench.steps, "Time steps to time")
      ->check(CLI::Range(2, 1000000000))
      ->capture_default_str();
  cmd_bench->add_option("--threads", bench.threads, "OpenMP threads (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (app.get_subcommands().empty()) {
    std::cout << app.help();
    return 0;
  }
  try {
    if (cmd_bench->parsed()) {
      bench.nx = modules[0];
      bench.ny = modules[1];
      bench.nz = modules[2];
      const ldem::BenchResult r = ldem::run_bench(bench);
      fmt::print("lattice {} x {} x {}: dt = {:.4g} s (stable {:.4g} s), {:.1f} bytes/module, "
                 "energy drift {:.2e}\n",
                 bench.nx, bench.ny, bench.nz, r.dt, r.dt_stable, r.bytes_per_module,
                 r.energy_drift);
      fmt::print("{}\n", ldem::bench_line(r));
    }
  } catch (const ldem::InputError& e) {
    fmt::print(stderr, "ldem: error: {}\n", e.what());
    return 2;
  }
  return 0;
}
