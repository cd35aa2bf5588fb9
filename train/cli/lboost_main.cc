// lboost: the LandmarkBoost command line. Every failure ends in one line "lboost <cmd>: error: ..."
// (control characters of file names escaped) and exit status 1; a requeue exits 75. The benchmarks
// are a tool of their own, lboost-bench (tools/bench).
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "train/cli/cli_util.h"
#include "train/cli/commands.h"

int main(int argc, char** argv) {
  CLI::App app{"LandmarkBoost: metric visual localization by landmark classification"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lboost 0.1.0");
  lmb::cli::add_world_command(app);
  lmb::cli::add_map_command(app);
  lmb::cli::add_areas_command(app);
  lmb::cli::add_bundle_command(app);
  lmb::cli::add_inspect_command(app);
  lmb::cli::add_vocab_command(app);
  lmb::cli::add_train_command(app);
  lmb::cli::add_export_command(app);
  lmb::cli::add_calibrate_command(app);
  lmb::cli::add_localize_command(app);
  lmb::cli::add_scene_command(app);
  lmb::cli::add_eval_command(app);
  lmb::cli::add_import_command(app);
  spdlog::set_pattern("[%H:%M:%S] %v");
  return lmb::cli::run_command_line(app, "lboost", argc, argv);
}
