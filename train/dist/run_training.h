// One training run of `lboost train` on the ranks of a communicator (one process or MPI ranks):
// rank 0 locks the run folder, the run is validated against the checkpoint it resumes (config, data
// source, feature space) before anything is written, each rank builds the training data and the
// feature columns it owns, the feature-parallel learner trains with checkpoints
// (training_job.h), and rank 0 writes config.toml, log.txt, metrics.jsonl, model.bin and
// summary.json (final validation P@1 next to the Hamming nearest-neighbour baseline; per-rank
// memory and communication). A refused run leaves the folder exactly as it was.
#pragma once

#include <string>

#include "train/boost/train_config.h"
#include "train/dist/communicator.h"

namespace lmb {

struct TrainRunInputs {
  std::string map, vocab;  // the map and vocabulary (not with a synthetic problem)
  std::string config;      // the config file given, named in errors ("" = none)
  std::string run_dir;     // the run folder
  std::string synthetic;   // a synthetic problem's preset (small, medium, paper) instead of a map
};

// Trains `config` on `in`. Collective. Returns false when a stop signal ended the run after its
// checkpoint (requeue), true when it finished. `step` names what the run is doing (for an
// out-of-memory error); `cross_fitting_folds`, when given, receives the number of fold models the
// model is to be cross-fitted with (cross_fitting_folds of train/boost/training_set.h; 0 for a fold
// model, an area or a synthetic problem). Throws lmb::Error (AgreedError when the ranks agree on it).
bool train_on_ranks(const TrainRunInputs& in, const TrainConfig& config, Communicator& comm, std::string* step,
                    int32_t* cross_fitting_folds = nullptr);

}  // namespace lmb
