// Each `lboost-bench` subcommand registers itself on the application through one of these. Every
// benchmark reports figures (never pass/fail) and prints the machine it ran on.
#pragma once

#include <CLI/CLI.hpp>

namespace lmb {
struct BoostBenchOptions;
}

namespace lmb::bench {

void add_context_bench(CLI::App& app);  // `context`: training feature vectors and used dims
void add_infer_bench(CLI::App& app);    // `infer`: inference stages against OpenCV's BFMatcher
void add_pose_bench(CLI::App& app);     // `pose`: the pose estimator at several settings
void add_bundle_bench(CLI::App& app);   // `bundle`: localization through a bundle of area models
void add_boost_bench(CLI::App& app);    // `boost`: the serial learner's seconds per round
void add_dist_bench(CLI::App& app);     // `dist`: the distributed learner (under mpirun)

// The options of `boost` and `dist`: the synthetic problem's shape (--classes, --observations,
// --background, --context-dims, --descriptor-bits, --density), --rounds and --dims-per-round. In
// boost_bench.cc.
void add_learner_shape_options(CLI::App* cmd, BoostBenchOptions* options);

}  // namespace lmb::bench
