#include "train/eval/methods.h"

#include <cmath>
#include <set>

#include "common/error.h"
#include "train/eval/descriptor_matchers.h"
#include "train/eval/landmarkboost_matcher.h"

namespace lmb {

namespace {

std::unique_ptr<Matcher> make_landmarkboost(const MethodContext& c, bool inverted_file) {
  ClassifierOptions options;
  options.top_k = c.options->top_k;
  options.use_inverted_file = inverted_file;
  if (inverted_file) options.inverted_file_words = c.options->inverted_file_words;
  options.min_margin = c.options->min_margin;
  // Ranking held-out map observations or calibration frames: the fusion's exemplars without them
  // (as the descriptor baselines' index; a class seen only there keeps its own).
  std::shared_ptr<const Model> model =
      c.excluded_from_fusion && c.excluded_keypoints != nullptr
          ? without_exemplars(c.model, *c.map, *c.excluded_keypoints, /*keep_sole=*/true)
          : c.model;
  return std::make_unique<LandmarkBoostMatcher>(std::move(model), options, !c.accept_only);
}

DescriptorMatcherOptions knn_options(const MethodContext& c) {
  DescriptorMatcherOptions o;
  o.top_k = c.options->top_k;
  o.knn_k = 4 * c.options->top_k;
  return o;
}

BruteforceHamming::Backend hamming_backend(const MethodContext& c) {
  return c.options->hamming_backend == "popcount" ? BruteforceHamming::Backend::kPopcount
                                                  : BruteforceHamming::Backend::kOpenCv;
}

std::unique_ptr<Matcher> make_bruteforce_hamming(const MethodContext& c) {
  return std::make_unique<DescriptorMatcher>(
      std::make_unique<HammingKnnIndex>(c.class_observations(), hamming_backend(c)), c.landmark_positions(),
      knn_options(c));
}

std::unique_ptr<Matcher> make_hamming_ratio(const MethodContext& c, RatioNeighbor neighbor) {
  DescriptorMatcherOptions o = knn_options(c);
  o.ratio_test = true;
  o.ratio = c.options->ratio;
  o.ratio_neighbor = neighbor;
  return std::make_unique<DescriptorMatcher>(
      std::make_unique<HammingKnnIndex>(c.class_observations(), hamming_backend(c)), c.landmark_positions(), o);
}

std::unique_ptr<Matcher> make_faiss_hnsw_ratio(const MethodContext& c) {
  DescriptorMatcherOptions o = knn_options(c);
  o.ratio_test = true;
  o.ratio = c.options->ratio;
  return std::make_unique<DescriptorMatcher>(std::make_unique<FaissHnswIndex>(c.class_observations(), c.options->faiss),
                                             c.landmark_positions(), o);
}

std::unique_ptr<Matcher> make_projected_kdtree(const MethodContext& c) {
  ProjectedKdTreeOptions kd;
  kd.dims = c.options->pca_dims;
  return std::make_unique<DescriptorMatcher>(std::make_unique<ProjectedKnnIndex>(c.class_observations(), kd),
                                             c.landmark_positions(), knn_options(c));
}

}  // namespace

void EvalOptions::check() const {
  LMB_CHECK(top_k >= 1 && top_k <= 10000, "eval: --top-k " << top_k << " must be in 1..10000");
  LMB_CHECK(inverted_file_words >= 1 && inverted_file_words <= 256,
            "eval: --inverted-file-words " << inverted_file_words << " must be in 1..256");
  LMB_CHECK(max_correspondences >= 0, "eval: --max-correspondences " << max_correspondences << " must be >= 0");
  LMB_CHECK(hamming_backend == "opencv" || hamming_backend == "popcount",
            "eval: --hamming-backend '" << hamming_backend << "' must be opencv or popcount");
  LMB_CHECK(std::isfinite(ratio) && ratio > 0.0 && ratio <= 1.0, "eval: --ratio " << ratio << " must be in (0, 1]");
  LMB_CHECK(!pose_thresholds.empty(), "eval: --pose-thresholds is empty");
  for (const PoseThresholds& t : pose_thresholds) t.check();
  sweep.check();
  calibration.check();
  faiss.check();
  std::set<std::string> seen;
  for (const std::string& m : methods) {
    find_eval_method(m);
    LMB_CHECK(seen.insert(m).second, "eval: --methods: '" << m << "' given twice");
  }
  std::set<std::string> sessions;
  for (const std::string& s : query_sessions) {
    LMB_CHECK(!s.empty(), "eval: --query-session: empty session name");
    LMB_CHECK(sessions.insert(s).second, "eval: --query-session: '" << s << "' given twice");
  }
  if (training_set) training_set->check();
  pose.check();
}

std::vector<std::string> EvalOptions::method_names() const {
  if (!methods.empty()) return methods;
  std::vector<std::string> all;
  for (const EvalMethod& m : eval_methods()) all.push_back(m.name);
  return all;
}

TrainingObservations MethodContext::class_observations() const {
  std::vector<landmark_t> classes;
  for (int32_t c = 0; c < model->num_classes(); ++c) classes.push_back(model->class_landmark(c));
  TrainingObservations obs =
      collect_training_observations(*map, classes, excluded_keypoints ? *excluded_keypoints : std::vector<int64_t>());
  LMB_CHECK(obs.size() > 0,
            options->map << ": the model's " << classes.size() << " landmarks have no observation in non-query frames");
  return obs;
}

std::vector<Eigen::Vector3d> MethodContext::landmark_positions() const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(map->landmarks.size());
  for (const Landmark& l : map->landmarks) out.push_back(l.position);
  return out;
}

const std::vector<EvalMethod>& eval_methods() {
  static const std::vector<EvalMethod> methods = {
      {"landmarkboost", "the inference library's classification, dense scoring of all classes",
       [](const MethodContext& c) { return make_landmarkboost(c, false); }},
      {"landmarkboost_invfile", "the same with the inverted file (the keypoint word's classes only)",
       [](const MethodContext& c) { return make_landmarkboost(c, true); }},
      {"bruteforce_hamming", "exact Hamming k-NN over the training observations (--hamming-backend)",
       make_bruteforce_hamming},
      {"hamming_ratio", "exact Hamming 1-NN with Lowe's ratio test against the nearest other landmark (--ratio)",
       [](const MethodContext& c) { return make_hamming_ratio(c, RatioNeighbor::kOtherLandmark); }},
      {"hamming_ratio_2nn",
       "the same against the 2nd nearest observation, whatever its landmark (OpenCV's 2-NN recipe)",
       [](const MethodContext& c) { return make_hamming_ratio(c, RatioNeighbor::kSecondObservation); }},
      {"projected_kdtree", "exact k-NN of PCA-projected descriptors (--pca-dims)", make_projected_kdtree},
      {"faiss_hnsw_ratio",
       "approximate Hamming k-NN (faiss IndexBinaryHNSW, --faiss-*) with hamming_ratio's ratio test",
       make_faiss_hnsw_ratio},
  };
  return methods;
}

const EvalMethod& find_eval_method(const std::string& name) {
  std::string known;
  for (const EvalMethod& m : eval_methods()) {
    if (m.name == name) return m;
    known += (known.empty() ? "" : ", ") + m.name;
  }
  LMB_FAIL("eval: --methods: unknown method '" << name << "' (known: " << known << ")");
}

}  // namespace lmb
