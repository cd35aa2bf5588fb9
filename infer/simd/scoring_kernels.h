// The batch scoring kernels of the classifier (infer/classifier.h), one table per SIMD level
// (common/simd/simd_level.h). Every level gives the same bits: fire masks and screening are integer
// work, and each lane's score is the same IEEE additions in the same order as the trainer's
// BoostModel::scores (no fused multiply-add: the build passes -ffp-contract=off).
#pragma once

#include <cstddef>
#include <cstdint>

#include "common/simd/simd_level.h"

namespace lmb::detail {

// Keypoints scored together, one lane each: a stump's fire bits of a batch are one uint32.
constexpr int32_t kScoringBatch = 32;
// Screening checkpoints: after every this many entries of a class's screening list
// (infer/detail/scoring_index.h).
constexpr int32_t kScreenCheck = 32;

// One stump of the inference model as the kernels read it (ScoringIndex::dense_stumps()).
struct DenseStump {
  int32_t used = 0;    // index into the model's used dims
  uint8_t theta = 0;   // fires when the value is > theta
  double above = 0.0;  // output when it fires: a + b
  double below = 0.0;  // b
};

// One class's exact sum in one 8-lane group of a batch (accumulate_groups).
struct GroupItem {
  double bias;
  const int32_t* stumps;  // the class's stump list (indices into the DenseStump array)
  int64_t count;
  int32_t group;  // lanes 8 group .. 8 group + 7
  double* out;    // 8 sums
};

// One class's screening data (ScoringIndex::screen_step and the screen_* arrays,
// infer/detail/scoring_index.h): its screening list (uint16 stump indices) with the stumps' 16-bit
// steps q, and per checkpoint the residue base low_ck and the added steps add_ck; at the end of the
// list low_c (end_low); the class's units_c.
struct ScreenList {
  const int16_t* q = nullptr;      // per stump of the model
  const uint16_t* list = nullptr;  // count entries
  int64_t count = 0;
  const uint16_t* check_low = nullptr;  // per checkpoint
  const int32_t* check_add = nullptr;
  uint16_t end_low = 0;
  int32_t units = 0;
};

struct ScoringKernels {
  SimdLevel level = SimdLevel::kGeneric;
  // fire[s] bit j = lane j's value of stump s's used dim is above the stump's theta; values holds
  // kScoringBatch lanes of used dim u at values[u * stride].
  void (*fire_masks)(const DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,
                     uint32_t* fire) = nullptr;
  // out[j] = bias + the outputs of stumps[0, count) in lane j, added in list order, each the stump's
  // above or below double as fire bit j says (kScoringBatch lanes).
  void (*accumulate_lanes)(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                           const uint32_t* fire, double* out) = nullptr;
  // Two classes at once, each with the additions of accumulate_lanes.
  void (*accumulate_two)(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                         int64_t count1, const DenseStump* dense, const uint32_t* fire, double* out0,
                         double* out1) = nullptr;
  // For each of the n items: out[l] = bias + the outputs of its stumps in lane 8 group + l, in
  // list order (the additions of accumulate_lanes).
  void (*accumulate_groups)(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire) = nullptr;
  // Screening of one class in `batches` (1 or 2) batches: bit 32 b + j of the result is set when
  // lane j of batch b is valid (bit j of valid[b]) and the class's integer bound from the fire
  // masks fire[b] passes the lane's goal goal[b][j] at every checkpoint (Classifier's
  // screen_goals); 0 as soon as a checkpoint fails in every valid lane of every batch. A batch
  // screened alone gives the same bits as in a pair. When residues is not null, each batch b with
  // a bit set gets residues[32 b + j] = the residue t_j at the end of the list in every lane j
  // (what the test at the end compares; screen_residues_pass tests it against other goals).
  uint64_t (*screen_class)(const ScreenList& list, int32_t batches, const uint32_t* const* fire,
                           const int32_t* const* goal, const uint32_t* valid, uint16_t* residues) = nullptr;
  // Whether some lane j < kScoringBatch has score[j] - background[j] > min_margin, score[j] >=
  // min_score and score[j] >= cutoff[j].
  bool (*any_lane_passes)(const double* score, const double* background, const double* cutoff, double min_margin,
                          double min_score) = nullptr;
};

// The table of this process's level (simd_level()).
const ScoringKernels& scoring_kernels();
// The table of `level`, or null when this CPU cannot run it.
const ScoringKernels* scoring_kernels(SimdLevel level);

// The kernels of each file; a level's table mixes them (scoring_generic.cc).
#define LMB_DECLARE_SCORING_KERNELS(isa)                                                                             \
  void fire_masks_##isa(const DenseStump* stumps, size_t num_stumps, const uint8_t* values, size_t stride,           \
                        uint32_t* fire);                                                                             \
  void accumulate_lanes_##isa(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,            \
                              const uint32_t* fire, double* out);                                                    \
  void accumulate_two_##isa(double bias0, const int32_t* stumps0, int64_t count0, double bias1,                      \
                            const int32_t* stumps1, int64_t count1, const DenseStump* dense, const uint32_t* fire,   \
                            double* out0, double* out1);                                                             \
  void accumulate_groups_##isa(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire);    \
  uint64_t screen_class_##isa(const ScreenList& list, int32_t batches, const uint32_t* const* fire,                  \
                              const int32_t* const* goal, const uint32_t* valid, uint16_t* residues);                \
  bool any_lane_passes_##isa(const double* score, const double* background, const double* cutoff, double min_margin, \
                             double min_score);
LMB_DECLARE_SCORING_KERNELS(generic)
LMB_DECLARE_SCORING_KERNELS(avx2)
LMB_DECLARE_SCORING_KERNELS(neon)
#undef LMB_DECLARE_SCORING_KERNELS
// AVX-512 (F, BW, DQ, VL): the accumulations and the screening; fire masks and the lane test are
// the AVX2 ones.
void accumulate_lanes_avx512(double bias, const int32_t* stumps, int64_t count, const DenseStump* dense,
                             const uint32_t* fire, double* out);
void accumulate_two_avx512(double bias0, const int32_t* stumps0, int64_t count0, double bias1, const int32_t* stumps1,
                           int64_t count1, const DenseStump* dense, const uint32_t* fire, double* out0, double* out1);
void accumulate_groups_avx512(const GroupItem* items, int32_t n, const DenseStump* dense, const uint32_t* fire);
uint64_t screen_class_avx512(const ScreenList& list, int32_t batches, const uint32_t* const* fire,
                             const int32_t* const* goal, const uint32_t* valid, uint16_t* residues);

}  // namespace lmb::detail
