// What the command-line tools `lboost` and `lboost-bench` share (library lmb_cli_util): the one-line
// error convention, the seed options, the warnings of a bundle's unloadable areas and the input
// files of a bundle.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/file_io.h"

namespace lmb::cli {

// Thrown by a command to end the tool with this exit code and no error line (e.g. 75 = requeue).
struct CommandExit {
  int code = 0;
};

// `message` on one line: line breaks, NUL and other control characters (from file names or
// content quoted in an error) become \n, \0, \t, \xNN escapes (escape_control_bytes).
std::string one_line(const std::string& message);

// Parses the command line into `app` and runs the chosen command's callback. Every failure ends in
// one line "PROGRAM <cmd>: error: ..." on stderr (<cmd>: the subcommands parsed, e.g. "import
// colmap"; control characters escaped) and exit status 1; --help and --version print and return
// 0; a CommandExit returns its code. Returns the process's exit status.
int run_command_line(CLI::App& app, const std::string& program, int argc, char** argv);

// Registers the seed option `name` (e.g. "--seed") of `cmd`, bound to `value`. Every seed option
// takes a decimal integer in 0..9223372036854775807 (2^63 - 1, the range of a config file's
// integers) and refuses anything else (negative, larger, hexadecimal, not a number) with one line
// naming the option. The plain form shows its default in the help.
CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, uint64_t* value, const std::string& help);
CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, std::optional<uint64_t>* value,
                             const std::string& help);

// Whether `path` names an image the commands read, by its extension (any case): png, jpg, jpeg,
// bmp, ppm, pgm, tif, tiff.
bool is_image_file(const std::filesystem::path& path);
// Those extensions, for messages: "png, jpg, jpeg, bmp, ppm, pgm, tif, tiff".
extern const char* const kImageExtensions;

// One line on stderr per area of a bundle that could not be loaded: "PROGRAM COMMAND: warning:
// <error> (the bundle's other areas were scored)".
void warn_area_errors(const std::string& program, const std::string& command,
                      const std::vector<std::string>& area_errors);

// The inputs of a bundle (docs/areas.md) for check_outputs_not_inputs, each named `what`: the
// index and the area model files it lists (the index alone when it cannot be read: the command
// reports why when it opens it). Nothing for an empty `index`. In command_paths.cc.
std::vector<NamedPath> bundle_input_paths(const std::string& index, const std::string& what);
// The area models (area-ID.lbm) in `folder` that `lboost bundle` reads, each named `what`.
std::vector<NamedPath> area_model_paths(const std::string& folder, const std::string& what);

}  // namespace lmb::cli
