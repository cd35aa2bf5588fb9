#include "train/dist/dist_bench.h"

#include <chrono>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/file_container.h"
#include "common/machine_info.h"
#include "train/boost/boost_model.h"
#include "train/dist/feature_parallel_learner.h"

namespace lmb {

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

FeatureMatrix keep_rank_columns(FeatureMatrix&& all, int rank, int size) {
  FeatureMatrix f;
  f.num_samples = all.num_samples;
  f.num_dims = all.num_dims;
  f.dims = rank_dims(all.num_dims, rank, size);
  LMB_CHECK(all.dims.empty(), "keep_rank_columns: the matrix must store every dim");
  f.data.resize(f.dims.size() * static_cast<size_t>(all.num_samples));
  for (size_t i = 0; i < f.dims.size(); ++i) {
    std::copy_n(all.column(f.dims[i]), all.num_samples, f.column(static_cast<int32_t>(i)));
  }
  all = FeatureMatrix();
  return f;
}

std::string run_dist_bench(Communicator& comm, const BoostBenchOptions& options) {
  nlohmann::json j;
  auto t0 = Clock::now();
  SyntheticBoostProblem problem = make_synthetic_boost_problem(options.data);
  j["data_seconds"] = since(t0);
  const FeatureMatrix features = keep_rank_columns(std::move(problem.features), comm.rank(), comm.size());
  BoostOptions bo = options.boost;
  bo.num_rounds = options.rounds;
  t0 = Clock::now();
  FeatureParallelLearner learner(comm, features, problem.set, bo);
  learner.initialize();
  j["setup_seconds"] = since(t0);
  comm.barrier();
  const int64_t sent0 = comm.bytes_sent(), received0 = comm.bytes_received();
  RoundTotals t;
  t0 = Clock::now();
  const double cpu0 = cpu_seconds();
  learner.train([&](const RoundStats& s) { t.add(s); });
  const double cpu = cpu_seconds() - cpu0;
  comm.barrier();
  const double wall = since(t0);
  const double n = options.rounds;
  const int64_t sent = comm.bytes_sent() - sent0, received = comm.bytes_received() - received0;
  j["ranks"] = comm.size();
  j["rounds"] = options.rounds;
  j["num_samples"] = problem.set.num_samples();
  j["num_classes"] = problem.set.num_classes;
  j["num_dims"] = features.num_dims;
  j["dims_per_round"] = bo.dims_per_round;
  j["seconds_per_round"] = wall / n;
  // CPU time: fair on a shared machine; the slowest rank's CPU per round bounds the wall time on
  // idle cores (the ranks wait for each other every round).
  j["cpu_seconds_per_round_max_rank"] =
      static_cast<double>(comm.allreduce_max(static_cast<int64_t>(cpu * 1e6))) / 1e6 / n;
  j["cpu_seconds_per_round_sum_ranks"] =
      static_cast<double>(comm.allreduce_sum(static_cast<int64_t>(cpu * 1e6))) / 1e6 / n;
  j["rank0_seconds_per_round"] = {{"histogram", t.histogram / n},
                                  {"search", t.search / n},
                                  {"update", t.update / n},
                                  {"eval_and_mining", t.eval / n}};
  j["mean_sharing_size"] = t.sharing_size / n;
  const std::string model = serialize_boost_model(learner.model());
  j["model_crc32"] = crc32(reinterpret_cast<const uint8_t*>(model.data()), model.size());  // same for any R
  // Per rank: the max over ranks of bytes and memory, and rank 0's own.
  j["bytes_sent_per_round_max_rank"] = static_cast<double>(comm.allreduce_max(sent)) / n;
  j["bytes_received_per_round_max_rank"] = static_cast<double>(comm.allreduce_max(received)) / n;
  j["bytes_sent_per_round_all_ranks"] = static_cast<double>(comm.allreduce_sum(sent)) / n;
  j["feature_mb_max_rank"] =
      static_cast<double>(comm.allreduce_max(static_cast<int64_t>(features.data.size()))) / 1048576.0;
  j["rss_mb_training_max_rank"] = static_cast<double>(comm.allreduce_max(static_cast<int64_t>(current_rss_mb())));
  j["peak_rss_mb_max_rank"] = static_cast<double>(comm.allreduce_max(static_cast<int64_t>(peak_rss_mb())));
  return j.dump(2);
}

}  // namespace lmb
