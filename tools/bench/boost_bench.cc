// `lboost-bench boost`: seconds per round of the serial JointBoost learner on one core, on
// synthetic data of the paper's shape by default (train/boost/boost_bench.h). The machine goes to
// stderr, the JSON report to stdout (and --json).
#include <cstdio>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "common/file_io.h"
#include "common/machine_info.h"
#include "tools/bench/bench_commands.h"
#include "train/boost/boost_bench.h"

namespace lmb::bench {

namespace {

struct BoostBenchArgs {
  BoostBenchOptions options;
  std::string json;
};

void run_boost_bench_command(const BoostBenchArgs& a) {
  if (!a.json.empty()) check_writable_file(a.json, "--json");
  std::fprintf(stderr, "lboost-bench boost: machine %s\n", machine_info().summary().c_str());
  const std::string report = run_boost_bench(a.options).to_json();
  std::printf("%s\n", report.c_str());
  if (!a.json.empty()) write_file_atomically(a.json, report + "\n");
}

}  // namespace

void add_learner_shape_options(CLI::App* cmd, BoostBenchOptions* options) {
  BoostBenchOptions& o = *options;
  cmd->add_option("--classes", o.data.num_classes, "Landmark classes (paper: 7,500)")->capture_default_str();
  cmd->add_option("--observations", o.data.observations_per_class, "Observations per class")->capture_default_str();
  cmd->add_option("--background", o.data.num_background, "Background samples")->capture_default_str();
  cmd->add_option("--context-dims", o.data.context_dims, "Context dims")->capture_default_str();
  cmd->add_option("--descriptor-bits", o.data.descriptor_bits, "Descriptor bits")->capture_default_str();
  cmd->add_option("--density", o.data.noise_density, "Share of non-zero context bins")->capture_default_str();
  cmd->add_option("--rounds", o.rounds, "Timed rounds")->capture_default_str();
  cmd->add_option("--dims-per-round", o.boost.dims_per_round, "Dims drawn a round, |F_m| (paper: 500)")
      ->capture_default_str();
}

void add_boost_bench(CLI::App& app) {
  auto args = std::make_shared<BoostBenchArgs>();
  BoostBenchOptions& o = args->options;
  auto* cmd = app.add_subcommand(
      "boost", "Seconds per boosting round of the serial learner on one core, synthetic data of the paper's shape");
  add_learner_shape_options(cmd, &o);
  cmd->add_option("--thresholds", o.boost.screening.max_thresholds, "Candidate thresholds per dim")
      ->capture_default_str();
  cmd->add_option("--negatives", o.boost.negatives.per_class, "Initial negatives per class")->capture_default_str();
  cmd->add_option("--refine-top", o.boost.screening.refine_top, "Candidates given the full sharing search")
      ->capture_default_str();
  cmd->add_option("--screening-step", o.boost.screening.step, "One alternation step in screening (0/1)")
      ->capture_default_str();
  cmd->add_option("--mining-interval", o.boost.mining.interval, "Rounds between negative mining passes")
      ->capture_default_str();
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_boost_bench_command(*args); });
}

}  // namespace lmb::bench
