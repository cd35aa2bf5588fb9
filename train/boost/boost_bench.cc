#include "train/boost/boost_bench.h"

#include <chrono>
#include <ctime>

#include <nlohmann/json.hpp>

#include "common/machine_info.h"
#include "train/boost/stump_learner.h"

namespace lmb {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

std::string BoostBenchResult::to_json() const {
  nlohmann::json j;
  j["num_samples"] = num_samples;
  j["num_classes"] = num_classes;
  j["num_dims"] = num_dims;
  j["num_entries"] = num_entries;
  j["data_seconds"] = data_seconds;
  j["setup_seconds"] = setup_seconds;
  j["seconds_per_round"] = seconds_per_round;
  j["cpu_seconds_per_round"] = cpu_seconds_per_round;
  j["histogram_fraction"] = histogram_fraction;
  j["search_fraction"] = search_fraction;
  j["update_fraction"] = update_fraction;
  j["eval_fraction"] = eval_fraction;
  j["mean_sharing_size"] = mean_sharing_size;
  j["last_cost"] = last_cost;
  j["peak_rss_mb"] = peak_rss_mb;
  j["feature_mb"] = feature_mb;
  return j.dump(2);
}

BoostBenchResult run_boost_bench(const BoostBenchOptions& options) {
  BoostBenchResult r;
  auto t0 = Clock::now();
  const SyntheticBoostProblem problem = make_synthetic_boost_problem(options.data);
  r.data_seconds = since(t0);
  BoostOptions bo = options.boost;
  bo.num_rounds = options.rounds;
  t0 = Clock::now();
  SerialStumpLearner learner(problem.features, problem.set, bo);
  learner.initialize();
  r.setup_seconds = since(t0);
  const double cpu0 = cpu_seconds();
  RoundTotals t;
  learner.train([&](const RoundStats& s) {
    t.add(s);
    r.last_cost = s.cost;
    r.num_entries = s.num_entries;
  });
  const double total = t.seconds;
  r.cpu_seconds_per_round = (cpu_seconds() - cpu0) / options.rounds;
  r.num_samples = problem.set.num_samples();
  r.num_classes = problem.set.num_classes;
  r.num_dims = problem.features.num_dims;
  r.seconds_per_round = total / options.rounds;
  if (total > 0) {
    r.histogram_fraction = t.histogram / total;
    r.search_fraction = t.search / total;
    r.update_fraction = t.update / total;
    r.eval_fraction = t.eval / total;
  }
  r.mean_sharing_size = t.sharing_size / options.rounds;
  r.peak_rss_mb = peak_rss_mb();
  r.feature_mb = static_cast<double>(problem.features.data.size()) / (1024.0 * 1024.0);
  return r;
}

}  // namespace lmb
