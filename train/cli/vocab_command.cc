#include "common/error.h"
#include "train/cli/commands.h"

namespace lmb::cli {

void add_vocab_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("vocab", "(under construction)");
  cmd->callback([] { LMB_FAIL("'vocab' is not built yet"); });
}

}  // namespace lmb::cli
