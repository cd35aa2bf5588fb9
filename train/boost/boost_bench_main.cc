// lmb_boost_bench: seconds per round of the serial learner on synthetic data of the paper's shape.
//   lmb_boost_bench [--classes 7500] [--rounds 10] [--dims-per-round 500] [--density 0.15] ...
#include <cstdio>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "common/machine_info.h"
#include "train/boost/boost_bench.h"

int main(int argc, char** argv) {
  lmb::BoostBenchOptions o;
  CLI::App app{"Seconds per boosting round on synthetic data of the paper's shape (one core)"};
  app.add_option("--classes", o.data.num_classes, "landmark classes");
  app.add_option("--observations", o.data.observations_per_class, "observations per class");
  app.add_option("--background", o.data.num_background, "background samples");
  app.add_option("--context-dims", o.data.context_dims, "context dims");
  app.add_option("--descriptor-bits", o.data.descriptor_bits, "descriptor bits");
  app.add_option("--density", o.data.noise_density, "fraction of non-zero context bins");
  app.add_option("--rounds", o.rounds, "timed rounds");
  app.add_option("--dims-per-round", o.boost.dims_per_round, "|F_m|");
  app.add_option("--thresholds", o.boost.screening.max_thresholds, "candidate thresholds per dim");
  app.add_option("--negatives", o.boost.negatives.per_class, "initial negatives per class");
  app.add_option("--refine-top", o.boost.screening.refine_top, "candidates given the full sharing search");
  app.add_option("--screening-step", o.boost.screening.step, "one alternation step in screening (0/1)");
  app.add_option("--mining-interval", o.boost.mining.interval, "mining interval (rounds)");
  CLI11_PARSE(app, argc, argv);
  try {
    std::fprintf(stderr, "lmb_boost_bench: machine %s\n", lmb::machine_info().summary().c_str());
    const lmb::BoostBenchResult r = lmb::run_boost_bench(o);
    std::printf("%s\n", r.to_json().c_str());
  } catch (const lmb::Error& e) {
    std::fprintf(stderr, "lmb_boost_bench: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
