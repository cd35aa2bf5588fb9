// The record of the feature space a classifier was trained in, so that no step can combine the
// trained stumps with another one and silently build a wrong model.
//
// A stump reads one dimension of the context embedding (common/context_embedding.h): regions x
// words + 8 x descriptor bytes dimensions, whose values depend on the exact region rectangles and
// the vocabulary's words; its classes are landmarks of the map the training set came from. The
// trainer records all of it in model.bin and in every checkpoint (train/boost/boost_model.h,
// train/checkpoint/checkpoint_h5.h): the rectangles themselves (export takes them from the record), and
// 64-bit fingerprints of the vocabulary and of the map. `lboost export` and a resumed
// `lboost train` build the same record from what they were given and refuse any difference.
//
// Serialized (cereal portable binary, inside those files): byte string `synthetic`, int32
// num_dims; then, when synthetic is empty, the regions (common/context_regions.h
// write_context_regions), int32 num_words, int32 descriptor_bytes, uint64 vocabulary_fingerprint,
// uint64 map_fingerprint, int64 map_landmarks, int64 map_keypoints.
#pragma once

#include <cstdint>
#include <string>

#include "common/context_regions.h"
#include "common/landmark_map.h"
#include "common/vocabulary.h"

namespace cereal {
class PortableBinaryOutputArchive;
}

namespace lmb {

class BoundedReader;  // common/bounded_reader.h

struct FeatureSpace {
  std::string synthetic;  // non-empty: a synthetic problem (train/boost/synthetic_problem.h), by name
  int32_t num_dims = 0;   // feature dimension the stumps index
  // A map's feature space (synthetic empty):
  ContextRegions regions;
  int32_t num_words = 0;
  int32_t descriptor_bytes = 0;
  uint64_t vocabulary_fingerprint = 0;  // fingerprint_vocabulary()
  uint64_t map_fingerprint = 0;         // fingerprint_map()
  int64_t map_landmarks = 0;            // informative (messages)
  int64_t map_keypoints = 0;

  bool is_synthetic() const { return !synthetic.empty(); }
};

// The feature space of training on `map` with `regions` and `vocabulary`.
FeatureSpace map_feature_space(const ContextRegions& regions, const Vocabulary& vocabulary, const LandmarkMap& map);
// The feature space of a synthetic problem of `num_dims` dimensions.
FeatureSpace synthetic_feature_space(const std::string& name, int32_t num_dims);

// 64-bit fingerprints (not cryptographic: they catch another file, not an attack). The same
// content gives the same value on every platform.
uint64_t fingerprint_vocabulary(const Vocabulary& vocabulary);
// Over everything training and export read from the map: detector, descriptor length, cameras,
// frames (camera, pose, gravity, query flag, keypoint range), keypoints, descriptors, keypoint
// landmarks and landmarks.
uint64_t fingerprint_map(const LandmarkMap& map);

// "" when `now` is the feature space `trained` records, else the first difference as a phrase:
// "the context regions differ (training: 1000 regions of seed 1; now: 1000 regions of seed 2)".
std::string feature_space_difference(const FeatureSpace& trained, const FeatureSpace& now);

void write_feature_space(cereal::PortableBinaryOutputArchive& ar, const FeatureSpace& space);
// Throws lmb::Error naming reader.what() for invalid contents; cereal::Exception past the end.
FeatureSpace read_feature_space(BoundedReader& reader);
// The same as a whole byte string; parse throws lmb::Error naming `what` (also when truncated or
// followed by extra bytes).
std::string serialize_feature_space(const FeatureSpace& space);
FeatureSpace parse_feature_space(const std::string& bytes, const std::string& what);

}  // namespace lmb
