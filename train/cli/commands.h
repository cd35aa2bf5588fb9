// Each `lboost` subcommand registers itself on the application through one of these.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace lmb {
struct BundleEvalOptions;
}

namespace lmb::cli {

// Thrown by a command to end `lboost` with this exit code and no error line (e.g. 75 = requeue).
struct CommandExit {
  int code = 0;
};

// `message` on one line: line breaks, NUL and other control characters (from file names or
// content quoted in an error) become \n, \0, \xNN escapes.
std::string one_line(const std::string& message);

void add_world_command(CLI::App& app);
void add_map_command(CLI::App& app);
void add_inspect_command(CLI::App& app);
void add_vocab_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_calibrate_command(CLI::App& app);  // in export_command.cc
void add_localize_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_bench_infer_command(CLI::App& app);   // `bench infer`, after add_bench_command
void add_bench_pose_command(CLI::App& app);    // `bench pose`, after add_bench_command
void add_bench_bundle_command(CLI::App& app);  // `bench bundle`, after add_bench_command
void add_import_command(CLI::App& app);        // `import` group: `import tum`, `import colmap`
void add_areas_command(CLI::App& app);
void add_bundle_command(CLI::App& app);
// The options of localization through a bundle that `localize` and `eval` share: --prior-noise,
// --no-prior, --prior-seed, --cache-areas (in bundle_command.cc).
void add_bundle_mode_options(CLI::App* cmd, BundleEvalOptions* options);
void add_bench_command(CLI::App& app);  // `bench` group: `bench context`, ...

}  // namespace lmb::cli
