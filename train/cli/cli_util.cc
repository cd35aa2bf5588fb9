#include "train/cli/cli_util.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include "common/text_lines.h"

namespace lmb::cli {

const char* const kImageExtensions = "png, jpg, jpeg, bmp, ppm, pgm, tif, tiff";

bool is_image_file(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* e : {".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".pgm", ".tif", ".tiff"}) {
    if (ext == e) return true;
  }
  return false;
}

std::string one_line(const std::string& message) { return escape_control_bytes(message); }

int run_command_line(CLI::App& app, const std::string& program, int argc, char** argv) {
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
    std::fprintf(stderr, "%s%s: error: %s\n", program.c_str(), command().c_str(), one_line(message).c_str());
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
  } catch (const CommandExit& e) {
    return e.code;
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  return 0;
}

namespace {

// The check of every seed option: digits only, at most 2^63 - 1. Rewrites the text in canonical
// decimal form (CLI11 would read a leading 0 as octal).
CLI::Validator seed_check() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        constexpr uint64_t kMax = static_cast<uint64_t>(std::numeric_limits<int64_t>::max());
        uint64_t value = 0;
        bool ok = !text.empty();
        for (const char c : text) {
          ok = ok && c >= '0' && c <= '9' && value <= (kMax - static_cast<uint64_t>(c - '0')) / 10;
          if (ok) value = value * 10 + static_cast<uint64_t>(c - '0');
        }
        if (!ok) return "'" + one_line(text) + "' must be an integer in 0.." + std::to_string(kMax);
        text = std::to_string(value);
        return "";
      },
      "0.." + std::to_string(std::numeric_limits<int64_t>::max()));
}

}  // namespace

CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, uint64_t* value, const std::string& help) {
  return cmd->add_option(name, *value, help)->transform(seed_check())->capture_default_str();
}

CLI::Option* add_seed_option(CLI::App* cmd, const std::string& name, std::optional<uint64_t>* value,
                             const std::string& help) {
  return cmd->add_option(name, *value, help)->transform(seed_check());
}

void warn_area_errors(const std::string& program, const std::string& command,
                      const std::vector<std::string>& area_errors) {
  for (const std::string& e : area_errors) {
    std::fprintf(stderr, "%s %s: warning: %s (the bundle's other areas were scored)\n", program.c_str(),
                 command.c_str(), one_line(e).c_str());
  }
}

}  // namespace lmb::cli
