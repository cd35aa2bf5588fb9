// Tracks from pairwise matches: union-find over keypoints that never merges two sets holding a
// keypoint of the same frame (such a merge would mean one world point seen twice in one image).
#pragma once

#include <cstdint>
#include <vector>

#include "common/types.h"

namespace lmb {

// A match between two keypoints by their global index (0..num_keypoints-1).
struct KeypointMatch {
  int64_t a = 0;
  int64_t b = 0;
  int32_t distance = 0;  // Hamming distance; matches merge in order of increasing distance
};

// Builds tracks of >= 2 keypoints. keypoint_frame[k] is the frame of keypoint k. Matches are
// applied in order of (distance, a, b); a match whose two sets share a frame is skipped, so no
// track holds two keypoints of one frame. Each track is sorted by keypoint index; tracks are
// ordered by their first keypoint. Deterministic for any input order of `matches`.
std::vector<std::vector<int64_t>> build_tracks(const std::vector<frame_t>& keypoint_frame,
                                               std::vector<KeypointMatch> matches);

}  // namespace lmb
