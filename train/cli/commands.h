// Each `lboost` subcommand registers itself on the application through one of these.
#pragma once

#include <CLI/CLI.hpp>

namespace lmb::cli {

void add_world_command(CLI::App& app);
void add_map_command(CLI::App& app);
void add_vocab_command(CLI::App& app);
void add_train_command(CLI::App& app);

}  // namespace lmb::cli
