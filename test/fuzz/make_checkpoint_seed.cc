// Writes the seed corpus of fuzz_checkpoint with the project's checkpoint writer:
// make_checkpoint_seed <out_dir> writes <out_dir>/ckpt-rounds{0,3}.h5, checkpoints of a small
// synthetic problem (8 classes) after 0 and 3 rounds. Separate from make_fuzz_seeds so that only
// this target needs the distributed layer (lmb_dist).
#include <cstdio>
#include <filesystem>

#include "train/boost/synthetic_problem.h"
#include "train/boost/train_config.h"
#include "train/dist/checkpoint_h5.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <out_dir>\n", argv[0]);
    return 2;
  }
  try {
    const std::filesystem::path out = argv[1];
    std::filesystem::create_directories(out);
    lmb::SyntheticBoostOptions o;
    o.num_classes = 8;
    const lmb::SyntheticBoostProblem problem = lmb::make_synthetic_boost_problem(o);
    lmb::TrainConfig config;
    config.boost.num_rounds = 3;
    config.boost.dims_per_round = 16;
    lmb::SerialStumpLearner learner(problem.features, problem.set, config.boost);
    for (int32_t rounds : {0, 3}) {
      while (learner.rounds_done() < rounds) learner.run_round();
      lmb::Checkpoint ck;
      ck.rounds = rounds;
      ck.seed = config.boost.seed;
      ck.config = lmb::train_config_toml(config);
      ck.data = "synthetic:fuzz";
      ck.state = learner.save_state();
      lmb::write_checkpoint(out / ("ckpt-rounds" + std::to_string(rounds) + ".h5"), ck);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_checkpoint_seed: %s\n", e.what());
    return 1;
  }
  return 0;
}
