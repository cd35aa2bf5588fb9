#include "common/error.h"
#include "train/cli/commands.h"

namespace lmb::cli {

void add_train_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("train", "(under construction)");
  cmd->callback([] { LMB_FAIL("'train' is not built yet"); });
}

}  // namespace lmb::cli
