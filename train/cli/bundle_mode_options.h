// The options of localization through a bundle of area models, one registration for every
// command that has them (lboost localize and eval, lboost-bench bundle): --prior-noise, --no-prior,
// --track and its options, the area search and winner, --area-threads, --prior-seed,
// --cache-areas; listed in the help under the heading "With --bundle".
#pragma once

#include <CLI/CLI.hpp>

#include "train/eval/bundle_eval.h"

namespace lmb::cli {

void add_bundle_mode_options(CLI::App* cmd, BundleEvalOptions* options);

}  // namespace lmb::cli
