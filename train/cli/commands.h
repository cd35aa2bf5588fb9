// Each `lboost` subcommand registers itself on the application through one of these.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "train/cli/cli_util.h"  // CommandExit, one_line, add_seed_option, bundle_input_paths, ...

namespace lmb {
struct BundleEvalOptions;
}

namespace lmb::cli {

// RUN/NAME, a file of a training run dir that a command reads ("" without a run dir).
inline std::filesystem::path run_file(const std::string& run_dir, const char* name) {
  return run_dir.empty() ? std::filesystem::path() : std::filesystem::path(run_dir) / name;
}

void add_world_command(CLI::App& app);
void add_map_command(CLI::App& app);
void add_inspect_command(CLI::App& app);
void add_vocab_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_calibrate_command(CLI::App& app);
void add_localize_command(CLI::App& app);
void add_scene_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_import_command(CLI::App& app);  // `import` group: `import tum`, `import colmap`, `import 7scenes`
void add_areas_command(CLI::App& app);
void add_bundle_command(CLI::App& app);
// One line on stderr per area of a bundle that could not be loaded, "lboost COMMAND: warning: ..."
// (`command`: "localize", "eval"; cli_util.h).
inline void warn_area_errors(const std::string& command, const std::vector<std::string>& area_errors) {
  warn_area_errors("lboost", command, area_errors);
}

}  // namespace lmb::cli
