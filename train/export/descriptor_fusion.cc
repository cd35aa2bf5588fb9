#include "train/export/descriptor_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"
#include "infer/classifier.h"
#include "infer/detail/scoring_index.h"
#include "train/features/build_features.h"

namespace lmb {

void DescriptorFusionOptions::check() const {
  LMB_CHECK(bin_width >= 1 && bin_width <= 64, "descriptor fusion: bin_width = " << bin_width << " must be in 1..64");
  LMB_CHECK(max_distance_samples >= 1,
            "descriptor fusion: max_distance_samples = " << max_distance_samples << " must be >= 1");
  LMB_CHECK(max_fit_samples >= 1, "descriptor fusion: max_fit_samples = " << max_fit_samples << " must be >= 1");
  LMB_CHECK(max_exemplars >= 0, "descriptor fusion: max_exemplars = " << max_exemplars << " must be >= 0");
  LMB_CHECK(!weights.empty(), "descriptor fusion: no candidate weights");
  for (size_t i = 0; i < weights.size(); ++i) {
    LMB_CHECK(
        std::isfinite(weights[i]) && weights[i] >= 0.0 && (i == 0 || weights[i] > weights[i - 1]),
        "descriptor fusion: weights must be finite, >= 0 and ascending (weights[" << i << "] = " << weights[i] << ")");
  }
}

namespace {

constexpr uint64_t kDistanceTag = 0x44495354;  // "DIST"
constexpr uint64_t kFitTag = 0x46495446;       // "FITF"

// The exemplars of each class, class after class, by ascending keypoint: every non-query map
// observation, or with cap > 0 k_centre_exemplars of those outside `held_out` (sorted keypoints:
// the held-out observations stay unseen descriptors, for the weight's fit here and for `lboost
// eval`'s held-out ranking; all of them for a class with no other).
struct Exemplars {
  std::vector<int64_t> begin;     // C + 1
  std::vector<int64_t> keypoint;  // per row
  std::vector<uint8_t> rows;      // descriptors
  std::vector<int32_t> cls;       // per row
};

Exemplars collect_exemplars(const LandmarkMap& map, const std::vector<landmark_t>& class_landmarks, int32_t cap,
                            const std::vector<int64_t>& held_out) {
  std::vector<std::vector<int64_t>> of = exemplar_keypoints(map, class_landmarks);
  if (cap > 0) {
    for (std::vector<int64_t>& keypoints : of) {
      std::vector<int64_t> seen;
      for (int64_t k : keypoints) {
        if (!std::binary_search(held_out.begin(), held_out.end(), k)) seen.push_back(k);
      }
      keypoints = k_centre_exemplars(map, seen.empty() ? keypoints : seen, cap);
    }
  }
  const int32_t C = static_cast<int32_t>(class_landmarks.size());
  Exemplars e;
  e.begin.assign(static_cast<size_t>(C) + 1, 0);
  const int bytes = map.descriptor_bytes;
  for (int32_t c = 0; c < C; ++c) {
    LMB_CHECK(!of[c].empty(), "descriptor fusion: class " << c << " has no map observation");
    for (int64_t k : of[c]) {
      e.keypoint.push_back(k);
      e.cls.push_back(c);
      e.rows.insert(e.rows.end(), map.descriptor(k), map.descriptor(k) + bytes);
    }
    e.begin[c + 1] = static_cast<int64_t>(e.keypoint.size());
  }
  return e;
}

// The `cap` items with the smallest counter_hash(seed, tag, keypoint), in their given order.
std::vector<int64_t> hash_subset(const std::vector<int64_t>& items, const std::vector<int64_t>& keypoint_of,
                                 int64_t cap, uint64_t seed, uint64_t tag) {
  if (static_cast<int64_t>(items.size()) <= cap) return items;
  std::vector<std::pair<uint64_t, size_t>> keyed(items.size());
  for (size_t i = 0; i < items.size(); ++i)
    keyed[i] = {counter_hash(seed, tag, static_cast<uint64_t>(keypoint_of[i])), i};
  std::nth_element(keyed.begin(), keyed.begin() + cap, keyed.end());
  std::vector<size_t> chosen;
  for (int64_t i = 0; i < cap; ++i) chosen.push_back(keyed[i].second);
  std::sort(chosen.begin(), chosen.end());
  std::vector<int64_t> out;
  for (size_t i : chosen) out.push_back(items[i]);
  return out;
}

// d[c] = the smallest distance of map keypoint k's descriptor to class c's exemplars, leaving out
// k's own row (a class whose only exemplar is k gets 8 * bytes + 1).
void class_distances(const Exemplars& e, const LandmarkMap& map, int64_t k, std::vector<uint16_t>* scratch,
                     std::vector<uint16_t>* d) {
  const int bytes = map.descriptor_bytes;
  const int64_t n = static_cast<int64_t>(e.keypoint.size());
  scratch->resize(static_cast<size_t>(n));
  hamming_rows(map.descriptor(k), e.rows.data(), n, bytes, scratch->data());
  const int32_t C = static_cast<int32_t>(e.begin.size()) - 1;
  d->assign(static_cast<size_t>(C), static_cast<uint16_t>(8 * bytes + 1));
  for (int64_t r = 0; r < n; ++r) {
    if (e.keypoint[r] == k) continue;
    uint16_t& best = (*d)[e.cls[r]];
    best = std::min(best, (*scratch)[r]);
  }
}

// Pool-adjacent-violators: the non-increasing sequence closest to y in weighted least squares.
std::vector<double> non_increasing_fit(const std::vector<double>& y, const std::vector<double>& w) {
  struct Block {
    double sum, weight;
    size_t count;
  };
  std::vector<Block> blocks;
  for (size_t i = 0; i < y.size(); ++i) {
    blocks.push_back({y[i] * w[i], w[i], 1});
    while (blocks.size() >= 2) {
      const Block& b = blocks[blocks.size() - 1];
      const Block& a = blocks[blocks.size() - 2];
      if (a.sum / a.weight >= b.sum / b.weight) break;  // non-increasing already
      const Block merged{a.sum + b.sum, a.weight + b.weight, a.count + b.count};
      blocks.pop_back();
      blocks.back() = merged;
    }
  }
  std::vector<double> out;
  for (const Block& b : blocks) out.insert(out.end(), b.count, b.sum / b.weight);
  return out;
}

// One held-out sample for the weight search: per distinct distance, the class with the largest
// stump sum there (ties: the smaller class), which is the only one of them the fused ranking can
// put first; and the true class.
struct FitSample {
  int64_t first = 0, last = 0;  // entries [first, last)
  int32_t truth = -1;
};
struct FitEntry {
  double score;
  int32_t cls;
  uint16_t distance;
};

// The fused first class of a sample (score + table[distance], higher first, ties: smaller class).
int32_t fused_first(const std::vector<FitEntry>& entries, const FitSample& s, const std::vector<double>& table) {
  double best = -std::numeric_limits<double>::infinity();
  int32_t best_cls = std::numeric_limits<int32_t>::max();
  for (int64_t i = s.first; i < s.last; ++i) {
    const double f = entries[i].score + table[entries[i].distance];
    if (f > best || (f == best && entries[i].cls < best_cls)) {
      best = f;
      best_cls = entries[i].cls;
    }
  }
  return best_cls;
}

// Step 1: g(d) at every distance 0..8 * bytes (and at the bin centres, *g_bins) from the
// training observations whose class has a second exemplar (leave-one-out). Returns g; *used: the
// observations behind it.
std::vector<double> distance_log_ratio(const Exemplars& ex, const LandmarkMap& map, const TrainingSet& set,
                                       const DescriptorFusionOptions& options, std::vector<double>* g_bins,
                                       int64_t* used) {
  const int32_t C = set.num_classes;
  const int32_t max_distance = 8 * map.descriptor_bytes;
  std::vector<int64_t> train_samples, train_keypoints;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    const int32_t c = set.sample_class[s];
    if (c >= C || set.sample_is_validation[s]) continue;
    // A class whose only exemplar is this observation has no distance to leave it out of.
    if (ex.begin[c + 1] - ex.begin[c] < 2 && ex.keypoint[ex.begin[c]] == set.sample_keypoint[s]) continue;
    train_samples.push_back(s);
    train_keypoints.push_back(set.sample_keypoint[s]);
  }
  LMB_CHECK(!train_samples.empty(),
            "descriptor fusion: no training observation has an exemplar of its class other than itself");
  const std::vector<int64_t> distance_samples =
      hash_subset(train_samples, train_keypoints, options.max_distance_samples, options.seed, kDistanceTag);
  *used = static_cast<int64_t>(distance_samples.size());
  const int32_t w = options.bin_width;
  const int32_t num_bins = max_distance / w + 1;
  std::vector<double> positives(static_cast<size_t>(num_bins), 0.0), negatives(positives);
  std::vector<uint16_t> scratch, dist;
  for (int64_t s : distance_samples) {
    const int32_t truth = set.sample_class[s];
    class_distances(ex, map, set.sample_keypoint[s], &scratch, &dist);
    for (int32_t c = 0; c < C; ++c) {
      if (dist[c] > max_distance) continue;  // a class whose only exemplar is this keypoint
      (c == truth ? positives : negatives)[dist[c] / w] += 1.0;
    }
  }
  double total_p = 0.0, total_n = 0.0;
  for (int32_t b = 0; b < num_bins; ++b) {
    total_p += positives[b];
    total_n += negatives[b];
  }
  std::vector<double> ratio(static_cast<size_t>(num_bins)), weight(static_cast<size_t>(num_bins));
  for (int32_t b = 0; b < num_bins; ++b) {
    ratio[b] = std::log((positives[b] + 0.5) / (total_p + 0.5 * num_bins)) -
               std::log((negatives[b] + 0.5) / (total_n + 0.5 * num_bins));
    weight[b] = positives[b] + negatives[b] + 1.0;
  }
  *g_bins = non_increasing_fit(ratio, weight);
  std::vector<double> g(static_cast<size_t>(max_distance) + 1);
  for (int32_t d = 0; d <= max_distance; ++d) {
    // Linear between bin centres (b * w + (w - 1) / 2), constant beyond the first and last.
    const double x = (d - 0.5 * (w - 1)) / w;
    const int32_t b0 = std::clamp(static_cast<int32_t>(std::floor(x)), 0, num_bins - 1);
    const int32_t b1 = std::min(b0 + 1, num_bins - 1);
    const double t = std::clamp(x - b0, 0.0, 1.0);
    g[d] = x <= 0.0 ? (*g_bins)[0] : (1.0 - t) * (*g_bins)[b0] + t * (*g_bins)[b1];
    // Between two equal bins the interpolation can round one ulp up: keep g non-increasing.
    if (d > 0) g[d] = std::min(g[d], g[d - 1]);
  }
  return g;
}

// The held-out map observations scored for step 2.
struct HeldOutScores {
  std::vector<FitSample> samples;
  std::vector<FitEntry> entries;
  int64_t hamming_hits = 0;  // samples whose nearest exemplar's class (ties: larger H) is the truth
};

// Step 2's inputs: the held-out observations' exact stump sums H of every class, batch by batch of
// Classifier::kBatch samples (the classifier's kernels, so the same doubles), reduced per sample to
// the entries fused_first reads. `held` / `held_keypoints`: the set's held-out landmark samples and
// their keypoints, in sample order.
HeldOutScores score_held_out(const Model& model, const LandmarkMap& map, const TrainingSet& set, const Exemplars& ex,
                             const std::vector<int64_t>& held, const std::vector<int64_t>& held_keypoints,
                             const DescriptorFusionOptions& options) {
  const int32_t C = model.num_classes();
  const int32_t max_distance = 8 * map.descriptor_bytes;
  std::vector<int64_t> fit_samples = hash_subset(held, held_keypoints, options.max_fit_samples, options.seed, kFitTag);
  const std::vector<frame_t> frame_of = keypoint_frames(map);
  std::stable_sort(fit_samples.begin(), fit_samples.end(), [&](int64_t a, int64_t b) {
    return frame_of[set.sample_keypoint[a]] < frame_of[set.sample_keypoint[b]];
  });
  const std::vector<uint8_t> words = keypoint_words(map, model.vocabulary());
  const std::shared_ptr<const Model> view(&model, [](const Model*) {});
  Classifier classifier(view);
  constexpr int32_t kBatch = Classifier::kBatch;
  const size_t U = model.scoring().used_dims().size();
  const std::vector<detail::DenseStump>& stumps = model.scoring().dense_stumps();
  const int64_t* begin = model.scoring().class_stump_begin().data();
  const int32_t* index = model.scoring().class_stump_index().data();
  const std::vector<double>& bias = model.data().bias;
  std::vector<uint8_t> values(U * kBatch, 0), one(U);
  std::vector<uint32_t> fire(stumps.size());
  std::vector<double> lane_scores(static_cast<size_t>(C) * kBatch);
  HeldOutScores out;
  std::vector<double> best_score(static_cast<size_t>(max_distance) + 1);
  std::vector<int32_t> best_cls(static_cast<size_t>(max_distance) + 1);
  std::vector<uint16_t> scratch, dist;
  std::vector<int64_t> batch;
  frame_t indexed = kInvalidFrameId;
  const detail::ScoringKernels& kernels = detail::scoring_kernels();
  auto flush = [&]() {
    const int32_t n = static_cast<int32_t>(batch.size());
    kernels.fire_masks(stumps.data(), stumps.size(), values.data(), kBatch, fire.data());
    double lanes[kBatch];
    for (int32_t c = 0; c < C; ++c) {
      kernels.accumulate_lanes(bias[c], index + begin[c], begin[c + 1] - begin[c], stumps.data(), fire.data(), lanes);
      for (int32_t j = 0; j < n; ++j) lane_scores[static_cast<size_t>(j) * C + c] = lanes[j];
    }
    for (int32_t j = 0; j < n; ++j) {
      const int64_t s = batch[j];
      const double* h = lane_scores.data() + static_cast<size_t>(j) * C;
      class_distances(ex, map, set.sample_keypoint[s], &scratch, &dist);
      std::fill(best_score.begin(), best_score.end(), -std::numeric_limits<double>::infinity());
      std::fill(best_cls.begin(), best_cls.end(), -1);
      for (int32_t c = 0; c < C; ++c) {
        const uint16_t d = std::min<uint16_t>(dist[c], static_cast<uint16_t>(max_distance));
        if (best_cls[d] < 0 || h[c] > best_score[d]) {  // ascending c: ties keep the smaller class
          best_score[d] = h[c];
          best_cls[d] = c;
        }
      }
      FitSample fs;
      fs.truth = set.sample_class[s];
      fs.first = static_cast<int64_t>(out.entries.size());
      int32_t nearest = -1;
      for (int32_t d = 0; d <= max_distance; ++d) {
        if (best_cls[d] < 0) continue;
        out.entries.push_back({best_score[d], best_cls[d], static_cast<uint16_t>(d)});
        if (nearest < 0) nearest = best_cls[d];
      }
      fs.last = static_cast<int64_t>(out.entries.size());
      out.hamming_hits += nearest == fs.truth;
      out.samples.push_back(fs);
    }
    batch.clear();
  };
  for (int64_t s : fit_samples) {
    const int64_t k = set.sample_keypoint[s];
    const frame_t f = frame_of[k];
    if (f != indexed) {
      classifier.index_frame(map_frame_keypoints(map, f, words), "descriptor fusion: map frame " + std::to_string(f));
      indexed = f;
    }
    classifier.compute_used_values(static_cast<int32_t>(k - map.frames[f].first_keypoint), map.descriptor(k),
                                   one.data());
    const size_t j = batch.size();
    for (size_t u = 0; u < U; ++u) values[u * kBatch + j] = one[u];
    batch.push_back(s);
    if (static_cast<int32_t>(batch.size()) == kBatch) flush();
  }
  if (!batch.empty()) flush();
  return out;
}

// P@1 of the held-out samples with distance_score = weight * g.
double fused_p1(const HeldOutScores& held, const std::vector<double>& g, double weight) {
  std::vector<double> table(g.size());
  for (size_t d = 0; d < g.size(); ++d) table[d] = weight * g[d];
  int64_t hits = 0;
  for (const FitSample& s : held.samples) hits += fused_first(held.entries, s, table) == s.truth;
  return static_cast<double>(hits) / static_cast<double>(held.samples.size());
}

// The index of the weight whose P@1, averaged with its grid neighbours', is largest (ties: smaller).
size_t plateau_middle(const std::vector<double>& p1) {
  const size_t K = p1.size();
  size_t chosen = 0;
  double chosen_smooth = -1.0;
  for (size_t i = 0; i < K; ++i) {
    const size_t lo = i == 0 ? 0 : i - 1, hi = std::min(K - 1, i + 1);
    double sum = 0.0;
    for (size_t k = lo; k <= hi; ++k) sum += p1[k];
    const double smooth = sum / static_cast<double>(hi - lo + 1);
    if (smooth > chosen_smooth) {
      chosen_smooth = smooth;
      chosen = i;
    }
  }
  return chosen;
}

}  // namespace

std::vector<std::vector<int64_t>> exemplar_keypoints(const LandmarkMap& map,
                                                     const std::vector<landmark_t>& class_landmarks) {
  std::vector<int32_t> class_of_landmark(map.landmarks.size(), -1);
  for (size_t c = 0; c < class_landmarks.size(); ++c) {
    const landmark_t l = class_landmarks[c];
    LMB_CHECK(l >= 0 && l < static_cast<landmark_t>(map.landmarks.size()),
              "descriptor fusion: class " << c << " landmark " << l << " is not in the map");
    class_of_landmark[l] = static_cast<int32_t>(c);
  }
  std::vector<std::vector<int64_t>> of(class_landmarks.size());
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l != kInvalidLandmarkId && class_of_landmark[l] >= 0) of[class_of_landmark[l]].push_back(k);
    }
  }
  for (std::vector<int64_t>& keypoints : of) std::sort(keypoints.begin(), keypoints.end());
  return of;
}

std::vector<int64_t> k_centre_exemplars(const LandmarkMap& map, const std::vector<int64_t>& keypoints, int32_t cap) {
  LMB_CHECK(cap >= 0, "descriptor fusion: max_exemplars = " << cap << " must be >= 0");
  const int64_t n = static_cast<int64_t>(keypoints.size());
  if (cap == 0 || n <= cap) return keypoints;
  const int bytes = map.descriptor_bytes;
  std::vector<uint8_t> rows(static_cast<size_t>(n * bytes));
  for (int64_t i = 0; i < n; ++i) std::copy_n(map.descriptor(keypoints[i]), bytes, rows.data() + i * bytes);
  // Pairwise distances, row by row (a class holds at most a few hundred observations).
  std::vector<uint16_t> d(static_cast<size_t>(n * n));
  for (int64_t i = 0; i < n; ++i) hamming_rows(rows.data() + i * bytes, rows.data(), n, bytes, d.data() + i * n);
  int64_t medoid = 0, best_sum = std::numeric_limits<int64_t>::max();
  for (int64_t i = 0; i < n; ++i) {
    int64_t sum = 0;
    for (int64_t j = 0; j < n; ++j) sum += d[i * n + j];
    if (sum < best_sum) {
      best_sum = sum;
      medoid = i;
    }
  }
  std::vector<int64_t> chosen = {medoid};
  std::vector<char> taken(static_cast<size_t>(n), 0);
  taken[medoid] = 1;
  std::vector<uint16_t> nearest(d.begin() + medoid * n, d.begin() + (medoid + 1) * n);
  while (static_cast<int64_t>(chosen.size()) < cap) {
    int64_t far = -1;
    for (int64_t j = 0; j < n; ++j) {
      if (!taken[j] && (far < 0 || nearest[j] > nearest[far])) far = j;
    }
    chosen.push_back(far);
    taken[far] = 1;
    for (int64_t j = 0; j < n; ++j) nearest[j] = std::min(nearest[j], d[far * n + j]);
  }
  std::sort(chosen.begin(), chosen.end());
  std::vector<int64_t> out;
  out.reserve(chosen.size());
  for (int64_t i : chosen) out.push_back(keypoints[i]);
  return out;
}

DescriptorFusion fit_descriptor_fusion(const Model& model, const LandmarkMap& map, const TrainingSet& set,
                                       const DescriptorFusionOptions& options, DescriptorFusionStats* stats) {
  options.check();
  const int32_t C = model.num_classes();
  LMB_CHECK(set.num_classes == C && set.class_landmark.size() == static_cast<size_t>(C),
            "descriptor fusion: the training set has " << set.num_classes << " classes, the model " << C);
  for (int32_t c = 0; c < C; ++c) {
    LMB_CHECK(set.class_landmark[c] == model.class_landmark(c),
              "descriptor fusion: class " << c << " is landmark " << set.class_landmark[c]
                                          << " in the training set but " << model.class_landmark(c)
                                          << " in the model (another run's model?)");
  }
  LMB_CHECK(map.descriptor_bytes == model.descriptor_bytes(),
            "descriptor fusion: the map has " << map.descriptor_bytes << "-byte descriptors, the model "
                                              << model.descriptor_bytes());
  // The held-out landmark samples: the weight is fitted on them, and capped exemplars leave them out.
  std::vector<int64_t> held, held_keypoints;
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    if (set.sample_class[s] >= C || !set.sample_is_validation[s]) continue;
    held.push_back(s);
    held_keypoints.push_back(set.sample_keypoint[s]);
  }
  LMB_CHECK(!held.empty(),
            "descriptor fusion: no held-out map observation to fit the weight on "
            "(training_set.validation_fraction is 0?)");
  std::vector<int64_t> held_sorted = held_keypoints;
  std::sort(held_sorted.begin(), held_sorted.end());
  const Exemplars ex = collect_exemplars(map, set.class_landmark, options.max_exemplars, held_sorted);

  // 1. The likelihood ratio of the distance from training observations (leave-one-out).
  std::vector<double> g_bins;
  int64_t distance_samples = 0;
  const std::vector<double> g = distance_log_ratio(ex, map, set, options, &g_bins, &distance_samples);

  // 2. The weight from the held-out observations.
  const HeldOutScores scores = score_held_out(model, map, set, ex, held, held_keypoints, options);
  std::vector<double> p1;
  for (double weight : options.weights) p1.push_back(fused_p1(scores, g, weight));
  const size_t chosen = plateau_middle(p1);
  const double alpha = options.weights[chosen];

  DescriptorFusion fusion;
  fusion.exemplar_begin = ex.begin;
  fusion.exemplars = ex.rows;
  fusion.distance_score.resize(g.size());
  for (size_t d = 0; d < g.size(); ++d) fusion.distance_score[d] = alpha * g[d];
  if (stats) {
    const double n = static_cast<double>(scores.samples.size());
    stats->weight = alpha;
    stats->exemplars = static_cast<int64_t>(ex.keypoint.size());
    stats->distance_samples = distance_samples;
    stats->fit_samples = static_cast<int64_t>(scores.samples.size());
    const auto zero = std::find(options.weights.begin(), options.weights.end(), 0.0);
    stats->fit_p1_without = zero != options.weights.end() ? p1[static_cast<size_t>(zero - options.weights.begin())]
                                                          : fused_p1(scores, g, 0.0);
    stats->fit_p1_with = p1[chosen];
    stats->fit_p1_hamming = static_cast<double>(scores.hamming_hits) / n;
    stats->weight_p1 = p1;
    stats->log_ratio = g_bins;
    stats->distance_ratio = g;
  }
  return fusion;
}

}  // namespace lmb
