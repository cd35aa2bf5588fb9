#include "common/error.h"
#include "train/cli/commands.h"

namespace lmb::cli {

void add_world_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("world", "(under construction)");
  cmd->callback([] { LMB_FAIL("'world' is not built yet"); });
}

}  // namespace lmb::cli
