// Seconds per boosting round at a given problem shape on one core (default: the paper's shape,
// see paper_shape_synthetic_options), peak memory, and where the time goes.
#pragma once

#include <cstdint>
#include <string>

#include "train/boost/boost_options.h"
#include "train/boost/synthetic_problem.h"

namespace lmb {

struct BoostBenchOptions {
  SyntheticBoostOptions data = paper_shape_synthetic_options();
  BoostOptions boost;   // num_rounds is overwritten by `rounds`
  int32_t rounds = 10;  // timed rounds (after initialization)
};

struct BoostBenchResult {
  int64_t num_samples = 0;
  int32_t num_classes = 0;
  int32_t num_dims = 0;
  int64_t num_entries = 0;
  double data_seconds = 0.0;           // synthetic data generation
  double setup_seconds = 0.0;          // learner construction (threshold layouts) + bootstrapping
  double seconds_per_round = 0.0;      // mean wall time over the timed rounds
  double cpu_seconds_per_round = 0.0;  // process CPU time per round (fair on a loaded machine)
  double histogram_fraction = 0.0, search_fraction = 0.0, update_fraction = 0.0, eval_fraction = 0.0;
  double mean_sharing_size = 0.0;
  double last_cost = 0.0;
  double peak_rss_mb = 0.0;  // getrusage peak resident set of the process
  double feature_mb = 0.0;   // the binned feature matrix alone
  std::string to_json() const;
};

BoostBenchResult run_boost_bench(const BoostBenchOptions& options);

}  // namespace lmb
