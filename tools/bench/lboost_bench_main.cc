// lboost-bench: the LandmarkBoost benchmarks, one subcommand each. Every failure ends in one line
// "lboost-bench <cmd>: error: ..." (control characters of file names escaped) and exit status 1,
// as in lboost.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "tools/bench/bench_commands.h"
#include "train/cli/cli_util.h"

int main(int argc, char** argv) {
  CLI::App app{"LandmarkBoost benchmarks: figures measured in one run, with the machine they ran on"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lboost-bench 0.1.0");
  lmb::bench::add_context_bench(app);
  lmb::bench::add_infer_bench(app);
  lmb::bench::add_pose_bench(app);
  lmb::bench::add_bundle_bench(app);
  lmb::bench::add_boost_bench(app);
  lmb::bench::add_dist_bench(app);
  spdlog::set_pattern("[%H:%M:%S] %v");
  return lmb::cli::run_command_line(app, "lboost-bench", argc, argv);
}
