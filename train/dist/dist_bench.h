// The distributed training benchmark (`mpirun -n R lboost-bench dist`): the feature-parallel
// learner on a synthetic problem (default: the paper's shape, see paper_shape_synthetic_options),
// per-round wall time, where it goes, bytes communicated per round, and memory per rank. Every rank
// generates the whole synthetic matrix and keeps its own columns (so the generator's peak is the
// full matrix; `rss_mb_training` is the footprint while training).
#pragma once

#include <cstdint>
#include <string>

#include "train/boost/boost_bench.h"
#include "train/dist/communicator.h"
#include "train/features/feature_matrix.h"

namespace lmb {

// The columns rank `rank` of `size` owns (rank_dims) of a matrix that stores every dim; frees `all`.
FeatureMatrix keep_rank_columns(FeatureMatrix&& all, int rank, int size);

// Collective. Returns the JSON report (complete on rank 0; other ranks get their own figures).
std::string run_dist_bench(Communicator& comm, const BoostBenchOptions& options);

}  // namespace lmb
