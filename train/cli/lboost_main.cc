// lboost: the LandmarkBoost command line. Every failure ends in one line "lboost <cmd>: error: ..."
// (control characters of file names escaped) and exit status 1; a requeue exits 75.
#include <cstdio>
#include <exception>
#include <string>

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "common/error.h"
#include "train/cli/commands.h"

namespace lmb::cli {

std::string one_line(const std::string& message) {
  std::string out;
  out.reserve(message.size());
  for (const char ch : message) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\0') {
      out += "\\0";
    } else if (c < 0x20 || c == 0x7F) {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02X", c);
      out += hex;
    } else {
      out += ch;
    }
  }
  return out;
}

}  // namespace lmb::cli

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
  lmb::cli::add_eval_command(app);
  lmb::cli::add_import_command(app);
  lmb::cli::add_bench_command(app);
  lmb::cli::add_bench_infer_command(app);
  lmb::cli::add_bench_pose_command(app);
  lmb::cli::add_bench_bundle_command(app);
  spdlog::set_pattern("[%H:%M:%S] %v");
  // The command of the message: the deepest subcommand parsed ("import colmap"), or none.
  auto command = [&app] {
    std::string name;
    for (const CLI::App* sub = &app; !sub->get_subcommands().empty();) {
      sub = sub->get_subcommands().front();
      name += " " + sub->get_name();
    }
    return name;
  };
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "lboost%s: error: %s\n", command().c_str(), lmb::cli::one_line(message).c_str());
    return 1;
  };
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line and status 1, like every other error (CLI11 prints two lines and exits 10x).
    return fail(std::string(e.what()) + " (see --help)");
  } catch (const lmb::cli::CommandExit& e) {
    return e.code;
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}
