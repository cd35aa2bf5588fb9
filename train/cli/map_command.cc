#include "common/error.h"
#include "train/cli/commands.h"

namespace lmb::cli {

void add_map_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("map", "(under construction)");
  cmd->callback([] { LMB_FAIL("'map' is not built yet"); });
}

}  // namespace lmb::cli
