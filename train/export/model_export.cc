#include "train/export/model_export.h"

#include <algorithm>

#include "common/error.h"
#include "train/features/build_features.h"

namespace lmb {

void ExportOptions::check() const {
  LMB_CHECK(min_word_observations >= 1,
            "export options: min_word_observations = " << min_word_observations << " must be >= 1");
}

ModelData export_model_data(const BoostModel& boost, const LandmarkMap& map, const Vocabulary& vocabulary,
                            const ContextRegions& regions, const ExportOptions& options, ExportStats* stats) {
  options.check();
  boost.check();
  const EmbeddingLayout layout = embedding_layout(map, regions, vocabulary);
  LMB_CHECK(boost.num_dims == layout.num_dims(), "export: the boost model has "
                                                     << boost.num_dims << " feature dims, but " << layout.num_regions
                                                     << " regions x " << layout.num_words << " words + "
                                                     << 8 * layout.descriptor_bytes << " bits = " << layout.num_dims()
                                                     << " (regions or vocabulary differ from training)");
  ModelData d;
  d.detector = map.detector;
  d.descriptor_bytes = map.descriptor_bytes;
  d.regions = regions;
  d.vocabulary = vocabulary;
  d.num_classes = boost.num_classes;
  d.class_landmark = boost.class_landmark;
  d.bias = boost.bias;
  const int32_t C = boost.num_classes;
  const landmark_t num_landmarks = static_cast<landmark_t>(map.landmarks.size());
  std::vector<int32_t> landmark_class(map.landmarks.size(), -1);
  for (int32_t c = 0; c < C; ++c) {
    const landmark_t id = boost.class_landmark[c];
    LMB_CHECK(id >= 0 && id < num_landmarks,
              "export: class " << c << " has landmark " << id << ", the map has " << num_landmarks);
    d.class_position.push_back(map.landmarks[id].position);
    landmark_class[id] = c;
  }
  for (const SharedStump& s : boost.stumps) {
    if (!s.classes.empty()) d.stumps.push_back(s);
  }

  // Inverted file from the map frames' observations of the class landmarks.
  const int32_t W = vocabulary.num_words();
  const std::vector<uint8_t> words = keypoint_words(map, vocabulary);
  std::vector<int32_t> count(static_cast<size_t>(C) * W, 0);
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t id = map.keypoint_landmark[k];
      if (id < 0 || landmark_class[id] < 0) continue;
      ++count[static_cast<size_t>(landmark_class[id]) * W + words[k]];
    }
  }
  d.inverted_file.assign(static_cast<size_t>(W), {});
  for (int32_t c = 0; c < C; ++c) {
    for (int32_t w = 0; w < W; ++w) {
      if (count[static_cast<size_t>(c) * W + w] >= options.min_word_observations) {
        d.inverted_file[w].push_back(c);
      }
    }
  }
  d.check("export");

  if (stats != nullptr) {
    *stats = ExportStats{};
    stats->num_classes = C;
    stats->num_stumps = static_cast<int32_t>(d.stumps.size());
    std::vector<int32_t> dims;
    for (const SharedStump& s : d.stumps) {
      dims.push_back(s.dim);
      stats->sharing_entries += static_cast<int64_t>(s.classes.size());
    }
    std::sort(dims.begin(), dims.end());
    stats->num_used_dims = static_cast<int32_t>(std::unique(dims.begin(), dims.end()) - dims.begin());
    int64_t observations = 0, candidates = 0;
    for (int32_t w = 0; w < W; ++w) {
      stats->inverted_file_entries += static_cast<int64_t>(d.inverted_file[w].size());
    }
    for (const MapFrame& f : map.frames) {
      if (f.is_query) continue;
      for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
        ++observations;
        candidates += static_cast<int64_t>(d.inverted_file[words[k]].size());
      }
    }
    stats->mean_candidates = observations > 0 ? static_cast<double>(candidates) / observations : 0.0;
  }
  return d;
}

}  // namespace lmb
