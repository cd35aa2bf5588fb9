// lboost: the LandmarkBoost command line. Every failure ends in one line "lboost <cmd>: error: ..."
// and a non-zero exit code.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "train/cli/commands.h"

int main(int argc, char** argv) {
  CLI::App app{"LandmarkBoost: metric visual localization by landmark classification"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lboost 0.1.0");
  lmb::cli::add_world_command(app);
  lmb::cli::add_map_command(app);
  lmb::cli::add_inspect_command(app);
  lmb::cli::add_vocab_command(app);
  lmb::cli::add_train_command(app);
  lmb::cli::add_export_command(app);
  lmb::cli::add_localize_command(app);
  lmb::cli::add_eval_command(app);
  lmb::cli::add_import_command(app);
  lmb::cli::add_bench_command(app);
  lmb::cli::add_bench_infer_command(app);
  spdlog::set_pattern("[%H:%M:%S] %v");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const lmb::cli::CommandExit& e) {
    return e.code;
  } catch (const lmb::Error& e) {
    const auto subs = app.get_subcommands();
    std::fprintf(stderr, "lboost %s: error: %s\n", subs.empty() ? "" : subs[0]->get_name().c_str(),
                 e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lboost: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
