// Training feature vectors for a landmark map: every requested sample keypoint's context embedding
// and descriptor bits (layout in common/context_embedding.h), binned to uint8 and stored
// column-major (train/features/feature_matrix.h).
#pragma once

#include <cstdint>
#include <vector>

#include "common/context_embedding.h"
#include "common/context_regions.h"
#include "common/landmark_map.h"
#include "common/vocabulary.h"
#include "train/features/augmentation.h"
#include "train/features/feature_matrix.h"

namespace lmb {

struct FeatureBuildOptions {
  int num_threads = 1;  // std::threads; the output does not depend on it
  // Global dimensions to store (sorted ascending, unique, each < num_dims); empty = all, in order.
  std::vector<int32_t> dims;
  // Per sample its augmentation copy (TrainingSet::sample_copy; empty = all 0): copy c > 0 takes its
  // context from augmented_frame(..., augment, c) (train/features/augmentation.h), whose keypoint
  // must be kept (augmented_keypoint_kept); its descriptor bits are the keypoint's own.
  std::vector<int32_t> copies;
  AugmentNoise augment;

  // Throws lmb::Error naming the field (num_threads outside 1..256, dims unsorted, duplicated or
  // out of range for `num_dims`, a negative copy, augment out of range).
  void check(int32_t num_dims) const;
};

// The embedding layout for a map, regions and vocabulary. Throws lmb::Error when the map's
// descriptor length differs from the vocabulary's.
EmbeddingLayout embedding_layout(const LandmarkMap& map, const ContextRegions& regions, const Vocabulary& vocabulary);

// Each keypoint's visual word (nearest vocabulary word), keypoints.size() entries. Throws
// lmb::Error when the descriptor lengths differ.
std::vector<uint8_t> keypoint_words(const LandmarkMap& map, const Vocabulary& vocabulary, int num_threads = 1);

// The gravity-aligned keypoints of one map frame (see common/context_embedding.h for the geometry)
// with the given per-keypoint words (all map keypoints). Throws lmb::Error naming the frame.
FrameKeypoints map_frame_keypoints(const LandmarkMap& map, frame_t frame, const std::vector<uint8_t>& words);

// Feature vectors of the given samples (global keypoint indices into map.keypoints, any frames,
// any order, repeats allowed): sample i is row i of every column. The context of a keypoint is
// made of all keypoints of its frame (of the frame's augmented copy for options.copies > 0).
// Samples are grouped by (frame, copy) so that each frame's index is built once a copy; threads take whole frames and
// write disjoint bytes, so the result is identical for any num_threads. Memory: num_samples * (stored dims) bytes, plus
// per thread one frame index and a row block of at most 256 samples. Throws lmb::Error for an index out of range, a
// descriptor length mismatch, or a frame with invalid geometry (the message names the frame), and
// when its buffers cannot be allocated (naming their size instead of a bare std::bad_alloc).
FeatureMatrix build_training_features(const LandmarkMap& map, const ContextRegions& regions,
                                      const Vocabulary& vocabulary, const std::vector<int64_t>& sample_keypoints,
                                      const FeatureBuildOptions& options);

// The bytes build_training_features allocates for `num_samples` samples of `stored_dims` stored
// dims (all of the layout's, or options.dims.size()) on `num_threads` threads: the matrix, each
// thread's row block and, for a share of the dims, the dim plan. Check it against the memory before
// building: the matrix is the run's largest allocation (regions x words context dims per sample).
int64_t training_feature_bytes(int64_t num_samples, int64_t stored_dims, int num_threads, bool all_dims = true);

// The frame of every keypoint (map.keypoints.size() entries). Throws lmb::Error when the frames'
// keypoint ranges are inconsistent with the keypoint array.
std::vector<frame_t> keypoint_frames(const LandmarkMap& map);

}  // namespace lmb
