// Real-rank tests of the distributed learner and the training loop (run under mpiexec -n 2 and
// -n 3 by ctest; every rank runs every test). Each compares against the serial learner trained
// in the same process on all columns: bit-identical models for any rank count, after a resume on
// another rank count, and after a stop requested by a signal on one rank.
#include "train/dist/feature_parallel_learner.h"

#include <unistd.h>

#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>
#include <mpi.h>
#include <spdlog/spdlog.h>

#include "train/boost/synthetic_problem.h"
#include "train/boost/train_config.h"
#include "train/dist/stop_signal.h"
#include "train/dist/training_job.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

struct Problem {
  SyntheticBoostProblem data;
  TrainConfig config;
};

Problem make_problem(int32_t rounds, int32_t refine_top) {
  Problem p;
  SyntheticBoostOptions o;
  o.num_classes = 60;
  o.context_dims = 384;
  o.descriptor_bits = 64;
  o.num_background = 300;
  p.data = make_synthetic_boost_problem(o);
  BoostOptions& b = p.config.boost;
  b.num_rounds = rounds;
  b.dims_per_round = 96;
  b.mining.interval = 7;  // several mining steps, one right after the resume point of some draws
  b.mining.pool_size = 400;
  b.negatives.per_class = 10;
  b.screening.refine_top = refine_top;
  b.seed = 11;
  return p;
}

// The columns `comm`'s rank owns, as the rank builds them in a real run.
FeatureMatrix own_columns(const FeatureMatrix& all, const Communicator& comm) {
  FeatureMatrix f;
  f.num_samples = all.num_samples;
  f.num_dims = all.num_dims;
  f.dims = rank_dims(all.num_dims, comm.rank(), comm.size());
  for (int32_t d : f.dims) f.data.insert(f.data.end(), all.column(d), all.column(d) + all.num_samples);
  return f;
}

BoostModel serial_model(const Problem& p) {
  SerialStumpLearner learner(p.data.features, p.data.set, p.config.boost);
  learner.train();
  return learner.model();
}

// A folder every rank of MPI_COMM_WORLD sees (rank 0 creates it).
fs::path shared_temp_dir(const char* tag) {
  Communicator world(MPI_COMM_WORLD);
  std::string path;
  if (world.rank() == 0) {
    path = (fs::temp_directory_path() / ("lmb_dist_" + std::string(tag) + "_" + std::to_string(::getpid()))).string();
    fs::remove_all(path);
    fs::create_directories(path);
  }
  world.broadcast_string(&path, 0);
  return path;
}

class FeatureParallel : public ::testing::TestWithParam<int32_t> {};

TEST_P(FeatureParallel, ModelIsBitIdenticalToSerial) {
  const Problem p = make_problem(30, GetParam());
  Communicator comm(MPI_COMM_WORLD);
  const FeatureMatrix mine = own_columns(p.data.features, comm);
  FeatureParallelLearner learner(comm, mine, p.data.set, p.config.boost);
  learner.train();
  SerialStumpLearner serial(p.data.features, p.data.set, p.config.boost);
  serial.train();
  const BoostModel& reference = serial.model();
  ASSERT_EQ(learner.model().stumps.size(), reference.stumps.size());
  for (size_t m = 0; m < reference.stumps.size(); ++m) {
    ASSERT_EQ(learner.model().stumps[m], reference.stumps[m]) << "round " << m << " on " << comm.size() << " ranks";
  }
  EXPECT_TRUE(learner.model() == reference);
  // The replicated state too: entries (with mined negatives) and their weights, bit for bit.
  const auto a = learner.entries(), b = serial.entries();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_TRUE(a[i].sample == b[i].sample && a[i].cls == b[i].cls && a[i].z == b[i].z && a[i].weight == b[i].weight)
        << "entry " << i;
  }
  EXPECT_EQ(learner.validation_precision(), serial.validation_precision());
  // The tracked rows (validation and mining pool scores) are split across ranks: each holds about
  // its share, and gathered on rank 0 they equal the serial learner's, float for float.
  const LearnerState state = learner.save_state(), reference_state = serial.save_state();
  if (comm.rank() == 0) {
    ASSERT_EQ(state.tracked_scores.size(), reference_state.tracked_scores.size());
    EXPECT_TRUE(std::memcmp(state.tracked_scores.data(), reference_state.tracked_scores.data(),
                            state.tracked_scores.size() * sizeof(float)) == 0);
  } else {
    EXPECT_TRUE(state.tracked_scores.empty());
  }
  // Every rank holds only its share of the columns.
  EXPECT_LE(mine.num_stored_columns(), (p.data.features.num_dims + comm.size() - 1) / comm.size());
}

// refine_top 32 (default screening + refinement) and 0 (exact search on every candidate).
INSTANTIATE_TEST_SUITE_P(RefineTop, FeatureParallel, ::testing::Values(32, 0));

// Trains with `comm` through the training loop to `rounds` (a final checkpoint), then resumes on
// every sub-communicator size 1..R and checks the finished model against the serial one.
TEST(TrainingJob, ResumeOnAnyRankCountIsBitIdentical) {
  Communicator world(MPI_COMM_WORLD);
  const int32_t total = 36;
  int64_t stop_at = 0;
  if (world.rank() == 0) stop_at = 1 + static_cast<int64_t>(std::random_device{}() % (total - 1));
  stop_at = world.allreduce_max(stop_at);
  std::printf("resume test: stopping at round %lld of %d\n", static_cast<long long>(stop_at), total);
  const Problem full = make_problem(total, 32);
  const BoostModel reference = serial_model(full);

  for (int ranks = 1; ranks <= world.size(); ++ranks) {
    const fs::path dir = shared_temp_dir("resume");
    TrainingJobOptions job;
    job.run_dir = dir;
    job.data = "synthetic:test";
    job.feature_space = synthetic_feature_space("synthetic:test", full.data.features.num_dims);
    // First part on all ranks of the world.
    {
      Problem part = make_problem(static_cast<int32_t>(stop_at), 32);
      job.config_toml = train_config_toml(part.config);
      const FeatureMatrix mine = own_columns(part.data.features, world);
      FeatureParallelLearner learner(world, mine, part.data.set, part.config.boost);
      const TrainingJobResult r = run_training_job(world, learner, job, find_resume_checkpoint(world, job), {});
      EXPECT_EQ(r.resumed_from, 0);
      EXPECT_EQ(learner.rounds_done(), stop_at);
    }
    // The rest on the first `ranks` ranks.
    MPI_Comm sub;
    MPI_Comm_split(MPI_COMM_WORLD, world.rank() < ranks ? 0 : MPI_UNDEFINED, world.rank(), &sub);
    if (sub != MPI_COMM_NULL) {
      Communicator comm(sub);
      job.config_toml = train_config_toml(full.config);
      const auto resume = find_resume_checkpoint(comm, job);
      ASSERT_TRUE(resume.has_value());
      EXPECT_EQ(resume->rounds, stop_at);
      EXPECT_EQ(resume->ranks, world.size());
      const FeatureMatrix mine = own_columns(full.data.features, comm);
      FeatureParallelLearner learner(comm, mine, full.data.set, full.config.boost);
      const TrainingJobResult r = run_training_job(comm, learner, job, resume, {});
      EXPECT_EQ(r.resumed_from, stop_at);
      EXPECT_TRUE(learner.model() == reference)
          << "resumed at " << stop_at << " on " << ranks << " of " << world.size() << " ranks";
      MPI_Comm_free(&sub);
    }
    world.barrier();
    if (world.rank() == 0) fs::remove_all(dir);
  }
}

// SIGUSR1 on the last rank only: every rank stops after the same round with a checkpoint, and the
// resumed run finishes with the serial model.
TEST(TrainingJob, SignalOnOneRankStopsAllAfterACheckpoint) {
  Communicator world(MPI_COMM_WORLD);
  const Problem p = make_problem(30, 32);
  const BoostModel reference = serial_model(p);
  const fs::path dir = shared_temp_dir("signal");
  TrainingJobOptions job;
  job.run_dir = dir;
  job.data = "synthetic:test";
  job.feature_space = synthetic_feature_space("synthetic:test", p.data.features.num_dims);
  job.config_toml = train_config_toml(p.config);
  job.checkpoint_interval = 4;
  job.checkpoint_keep = 2;
  const FeatureMatrix mine = own_columns(p.data.features, world);
  int32_t stopped_at = 0;
  {
    FeatureParallelLearner learner(world, mine, p.data.set, p.config.boost);
    const bool signaller = world.rank() == world.size() - 1;
    // Two rounds by hand, then the signal arrives before the loop's first round.
    install_stop_signal_handlers();
    learner.run_round();
    learner.run_round();
    if (signaller) std::raise(SIGUSR1);
    const TrainingJobResult r = run_training_job(world, learner, job, std::nullopt, {});
    EXPECT_TRUE(r.stopped);
    stopped_at = learner.rounds_done();
    EXPECT_EQ(stopped_at, 3);  // two rounds by hand, one in the loop, then the agreed stop
    EXPECT_EQ(world.allreduce_max(stopped_at), world.allreduce_sum(stopped_at) / world.size());
    clear_stop_signal();
  }
  world.barrier();
  EXPECT_TRUE(fs::exists(CheckpointDir(dir).path_for(stopped_at)));
  FeatureParallelLearner learner(world, mine, p.data.set, p.config.boost);
  const auto resume = find_resume_checkpoint(world, job);
  ASSERT_TRUE(resume.has_value());
  EXPECT_EQ(resume->rounds, stopped_at);
  const TrainingJobResult r = run_training_job(world, learner, job, resume, {});
  EXPECT_FALSE(r.stopped);
  EXPECT_TRUE(learner.model() == reference);
  // keep = 2: only the two newest checkpoints remain (the last is the final one).
  world.barrier();
  EXPECT_EQ(CheckpointDir(dir).list().size(), 2u);
  world.barrier();
  if (world.rank() == 0) fs::remove_all(dir);
}

// checkpoint.minutes: rank 0's clock decides and every rank follows (a rank that checkpointed
// alone would hang the gather); which rounds get a checkpoint leaves the model unchanged.
TEST(TrainingJob, CheckpointsWhenRankZerosClockSaysAndTheModelIsTheSame) {
  Communicator world(MPI_COMM_WORLD);
  const Problem p = make_problem(30, 32);
  const BoostModel reference = serial_model(p);
  const int32_t rounds = p.config.boost.num_rounds;
  ASSERT_GE(rounds, 3);
  const FeatureMatrix mine = own_columns(p.data.features, world);
  for (const double minutes : {1e-12, 1e6}) {
    const fs::path dir = shared_temp_dir(minutes < 1.0 ? "clock_due" : "clock_never");
    TrainingJobOptions job;
    job.run_dir = dir;
    job.data = "synthetic:test";
    job.feature_space = synthetic_feature_space("synthetic:test", p.data.features.num_dims);
    job.config_toml = train_config_toml(p.config);
    job.checkpoint_minutes = minutes;
    job.checkpoint_interval = 0;
    job.checkpoint_keep = rounds + 1;
    FeatureParallelLearner learner(world, mine, p.data.set, p.config.boost);
    const TrainingJobResult r = run_training_job(world, learner, job, std::nullopt, {});
    EXPECT_TRUE(learner.model() == reference) << "minutes " << minutes;
    // Due after every round, or never: then only the final checkpoint.
    const int32_t expected = minutes < 1.0 ? rounds : 1;
    EXPECT_EQ(r.checkpoints_written, expected) << "minutes " << minutes << " on rank " << world.rank();
    world.barrier();
    EXPECT_EQ(CheckpointDir(dir).list().size(), static_cast<size_t>(expected)) << "minutes " << minutes;
    world.barrier();
    if (world.rank() == 0) fs::remove_all(dir);
  }
  TrainingJobOptions bad;  // refused before any collective step
  bad.run_dir = "unused";
  bad.checkpoint_minutes = std::nan("");
  FeatureParallelLearner learner(world, mine, p.data.set, p.config.boost);
  EXPECT_THROW(run_training_job(world, learner, bad, std::nullopt, {}), Error);
}

}  // namespace
}  // namespace lmb

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  spdlog::set_level(spdlog::level::warn);  // the training loop's checkpoint lines
  const int failed = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return any;
}
