#include "train/eval/baselines.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

namespace {

bool neighbor_less(const Neighbor& a, const Neighbor& b) {
  return a.distance < b.distance || (a.distance == b.distance && a.index < b.index);
}

void check_observations(const TrainingObservations& obs, const char* who) {
  LMB_CHECK(obs.descriptor_bytes > 0, who << ": descriptor_bytes " << obs.descriptor_bytes << " must be > 0");
  LMB_CHECK(obs.size() > 0, who << ": no training observation");
  LMB_CHECK(static_cast<int64_t>(obs.descriptors.size()) == obs.size() * obs.descriptor_bytes,
            who << ": " << obs.descriptors.size() << " descriptor bytes for " << obs.size() << " observations of "
                << obs.descriptor_bytes << " bytes");
}

}  // namespace

TrainingObservations collect_training_observations(const LandmarkMap& map,
                                                   const std::vector<landmark_t>& selected_landmarks,
                                                   const std::vector<int64_t>& excluded_keypoints) {
  const int64_t num_kp = static_cast<int64_t>(map.keypoints.size());
  LMB_CHECK(map.descriptor_bytes > 0,
            "collect_training_observations: map descriptor_bytes is " << map.descriptor_bytes);
  LMB_CHECK(static_cast<int64_t>(map.keypoint_landmark.size()) == num_kp &&
                static_cast<int64_t>(map.descriptors.size()) == num_kp * map.descriptor_bytes,
            "collect_training_observations: map keypoint, landmark and descriptor counts disagree");
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  std::vector<char> selected(static_cast<size_t>(num_landmarks), selected_landmarks.empty() ? 1 : 0);
  for (landmark_t l : selected_landmarks) {
    LMB_CHECK(l >= 0 && l < num_landmarks,
              "collect_training_observations: selected landmark " << l << " out of range [0, " << num_landmarks << ")");
    selected[static_cast<size_t>(l)] = 1;
  }
  TrainingObservations obs;
  obs.descriptor_bytes = map.descriptor_bytes;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    LMB_CHECK(f.first_keypoint >= 0 && f.num_keypoints >= 0 && f.first_keypoint + f.num_keypoints <= num_kp,
              "collect_training_observations: frame " << f.name << " keypoint range out of bounds");
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[static_cast<size_t>(k)];
      if (l == kInvalidLandmarkId) continue;
      LMB_CHECK(l >= 0 && l < num_landmarks,
                "collect_training_observations: keypoint " << k << " has landmark " << l << " out of range");
      if (!selected[static_cast<size_t>(l)]) continue;
      if (std::binary_search(excluded_keypoints.begin(), excluded_keypoints.end(), k)) continue;
      obs.landmark.push_back(l);
      const uint8_t* d = map.descriptor(k);
      obs.descriptors.insert(obs.descriptors.end(), d, d + map.descriptor_bytes);
    }
  }
  return obs;
}

std::vector<RankedCandidate> neighbors_to_candidates(const std::vector<Neighbor>& neighbors,
                                                     const std::vector<landmark_t>& landmark_of_observation) {
  std::vector<RankedCandidate> out;
  out.reserve(neighbors.size());
  for (const Neighbor& nb : neighbors) {
    const landmark_t l = landmark_of_observation[static_cast<size_t>(nb.index)];
    bool seen = false;
    for (const RankedCandidate& c : out) seen = seen || c.landmark == l;
    if (!seen) out.push_back(RankedCandidate{l, -nb.distance});
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

BruteforceHamming::BruteforceHamming(TrainingObservations observations, Backend backend)
    : obs_(std::move(observations)), backend_(backend) {
  check_observations(obs_, "BruteforceHamming");
  LMB_CHECK(obs_.descriptor_bytes * 8 <= 65535,
            "BruteforceHamming: descriptors of " << obs_.descriptor_bytes << " bytes are too long");
}

std::vector<Neighbor> BruteforceHamming::knn(const uint8_t* descriptor, int k) const {
  LMB_CHECK(k >= 1, "BruteforceHamming::knn: k " << k << " must be >= 1");
  if (backend_ == Backend::kOpenCv) return knn_opencv(descriptor, 1, k)[0];
  const int64_t n = obs_.size();
  std::vector<uint16_t> dist(static_cast<size_t>(n));
  hamming_rows(descriptor, obs_.descriptors.data(), n, obs_.descriptor_bytes, dist.data());
  // Counting selection: the k-th smallest distance from a histogram, then one pass in index order.
  const int max_d = obs_.descriptor_bytes * 8;
  std::vector<int64_t> hist(static_cast<size_t>(max_d) + 1, 0);
  for (uint16_t d : dist) ++hist[d];
  const int64_t want = std::min<int64_t>(k, n);
  int kth = 0;
  int64_t below = 0;  // count with distance < kth
  while (below + hist[static_cast<size_t>(kth)] < want) below += hist[static_cast<size_t>(kth++)];
  int64_t ties_left = want - below;
  std::vector<Neighbor> out;
  out.reserve(static_cast<size_t>(want));
  for (int64_t i = 0; i < n; ++i) {
    const int d = dist[static_cast<size_t>(i)];
    if (d < kth || (d == kth && ties_left-- > 0)) out.push_back(Neighbor{i, static_cast<double>(d)});
  }
  std::sort(out.begin(), out.end(), neighbor_less);
  return out;
}

std::vector<std::vector<Neighbor>> BruteforceHamming::knn_opencv(const uint8_t* descriptors, int64_t num, int k) const {
  const cv::Mat train(static_cast<int>(obs_.size()), obs_.descriptor_bytes, CV_8U,
                      const_cast<uint8_t*>(obs_.descriptors.data()));
  const cv::Mat query(static_cast<int>(num), obs_.descriptor_bytes, CV_8U, const_cast<uint8_t*>(descriptors));
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> matches;
  matcher.knnMatch(query, train, matches, k);
  std::vector<std::vector<Neighbor>> out(static_cast<size_t>(num));
  for (size_t q = 0; q < matches.size() && q < out.size(); ++q) {
    for (const cv::DMatch& m : matches[q]) {
      if (m.trainIdx < 0) continue;
      out[q].push_back(Neighbor{m.trainIdx, static_cast<double>(m.distance)});
    }
    std::sort(out[q].begin(), out[q].end(), neighbor_less);  // canonical order among equal distances
  }
  return out;
}

std::vector<RankedCandidate> BruteforceHamming::query(const uint8_t* descriptor, int k) const {
  return neighbors_to_candidates(knn(descriptor, k), obs_.landmark);
}

std::vector<std::vector<Neighbor>> BruteforceHamming::knn_batch(const uint8_t* descriptors, int64_t num, int k) const {
  LMB_CHECK(k >= 1, "BruteforceHamming::knn_batch: k " << k << " must be >= 1");
  if (num <= 0) return {};
  if (backend_ == Backend::kOpenCv) return knn_opencv(descriptors, num, k);
  std::vector<std::vector<Neighbor>> out(static_cast<size_t>(num));
  for (int64_t q = 0; q < num; ++q) out[static_cast<size_t>(q)] = knn(descriptors + q * obs_.descriptor_bytes, k);
  return out;
}

std::vector<std::vector<RankedCandidate>> BruteforceHamming::query_batch(const uint8_t* descriptors, int64_t num,
                                                                         int k) const {
  const std::vector<std::vector<Neighbor>> nn = knn_batch(descriptors, num, k);
  std::vector<std::vector<RankedCandidate>> out(nn.size());
  for (size_t q = 0; q < nn.size(); ++q) out[q] = neighbors_to_candidates(nn[q], obs_.landmark);
  return out;
}

// ---------------------------------------------------------------------------------------------

void ProjectedKdTreeOptions::check() const {
  LMB_CHECK(dims >= 1, "ProjectedKdTreeOptions: dims " << dims << " must be >= 1");
  LMB_CHECK(max_pca_samples >= 2, "ProjectedKdTreeOptions: max_pca_samples " << max_pca_samples << " must be >= 2");
  LMB_CHECK(leaf_size >= 1, "ProjectedKdTreeOptions: leaf_size " << leaf_size << " must be >= 1");
}

namespace {

void descriptor_bits(const uint8_t* d, int bits, float* out) {
  for (int b = 0; b < bits; ++b) out[b] = static_cast<float>(descriptor_bit(d, b));
}

}  // namespace

ProjectedKdTree::ProjectedKdTree(TrainingObservations observations, const ProjectedKdTreeOptions& options)
    : obs_(std::move(observations)), options_(options) {
  options_.check();
  check_observations(obs_, "ProjectedKdTree");
  const int bits = obs_.descriptor_bytes * 8;
  const int dims = options_.dims;
  LMB_CHECK(dims <= bits, "ProjectedKdTreeOptions: dims " << dims << " exceeds the " << bits << " descriptor bits");
  const int64_t n = obs_.size();

  // PCA on an even stride of at most max_pca_samples observations; covariance in double, by chunks.
  const int64_t stride = std::max<int64_t>(1, (n + options_.max_pca_samples - 1) / options_.max_pca_samples);
  std::vector<int64_t> sample;
  for (int64_t i = 0; i < n; i += stride) sample.push_back(i);
  const int64_t m = static_cast<int64_t>(sample.size());
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(bits);
  for (int64_t i : sample) {
    const uint8_t* d = obs_.descriptor(i);
    for (int b = 0; b < bits; ++b) mean[b] += descriptor_bit(d, b);
  }
  mean /= static_cast<double>(m);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(bits, bits);
  constexpr int64_t kChunk = 2048;
  Eigen::MatrixXd chunk(kChunk, bits);
  for (int64_t start = 0; start < m; start += kChunk) {
    const int64_t rows = std::min(kChunk, m - start);
    for (int64_t r = 0; r < rows; ++r) {
      const uint8_t* d = obs_.descriptor(sample[static_cast<size_t>(start + r)]);
      for (int b = 0; b < bits; ++b) chunk(r, b) = descriptor_bit(d, b) - mean[b];
    }
    cov.selfadjointView<Eigen::Lower>().rankUpdate(chunk.topRows(rows).transpose());
  }
  cov = cov.selfadjointView<Eigen::Lower>();
  cov /= static_cast<double>(m);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cov);
  LMB_CHECK(eig.info() == Eigen::Success, "ProjectedKdTree: PCA eigen decomposition failed");
  components_.resize(bits, dims);
  for (int j = 0; j < dims; ++j) {
    Eigen::VectorXd v = eig.eigenvectors().col(bits - 1 - j);  // descending eigenvalues
    Eigen::Index arg = 0;
    v.cwiseAbs().maxCoeff(&arg);
    if (v[arg] < 0) v = -v;  // deterministic sign
    components_.col(j) = v.cast<float>();
  }
  mean_ = mean.cast<float>();

  points_.resize(static_cast<size_t>(n * dims));
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::VectorXf p = project(obs_.descriptor(i));
    std::copy(p.data(), p.data() + dims, points_.data() + i * dims);
  }
  order_.resize(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) order_[static_cast<size_t>(i)] = i;
  nodes_.reserve(static_cast<size_t>(2 * (n / options_.leaf_size + 1)));
  build(0, n);
  // The points again in tree order, so that a leaf scans contiguous memory.
  tree_points_.resize(points_.size());
  for (int64_t i = 0; i < n; ++i) {
    const float* src = points_.data() + order_[static_cast<size_t>(i)] * dims;
    std::copy(src, src + dims, tree_points_.data() + i * dims);
  }
}

Eigen::VectorXf ProjectedKdTree::project(const uint8_t* descriptor) const {
  const int bits = obs_.descriptor_bytes * 8;
  Eigen::VectorXf x(bits);
  descriptor_bits(descriptor, bits, x.data());
  x -= mean_;
  return components_.transpose() * x;
}

float ProjectedKdTree::squared_distance(const float* a, const float* b, int dims) {
  float s = 0.f;
  for (int i = 0; i < dims; ++i) {
    const float d = a[i] - b[i];
    s += d * d;
  }
  return s;
}

int32_t ProjectedKdTree::build(int64_t begin, int64_t end) {
  const int dims = options_.dims;
  const int32_t id = static_cast<int32_t>(nodes_.size());
  nodes_.push_back(Node{});
  nodes_[static_cast<size_t>(id)].begin = begin;
  nodes_[static_cast<size_t>(id)].end = end;
  if (end - begin <= options_.leaf_size) return id;
  // Split on the dimension of largest spread, at the median.
  int best_dim = 0;
  float best_spread = 0.f;
  for (int d = 0; d < dims; ++d) {
    float lo = points_[static_cast<size_t>(order_[static_cast<size_t>(begin)] * dims + d)], hi = lo;
    for (int64_t i = begin; i < end; ++i) {
      const float v = points_[static_cast<size_t>(order_[static_cast<size_t>(i)] * dims + d)];
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    if (hi - lo > best_spread) {
      best_spread = hi - lo;
      best_dim = d;
    }
  }
  if (best_spread <= 0.f) return id;  // all points identical: one leaf
  const int64_t mid = begin + (end - begin) / 2;
  auto coord = [&](int64_t obs) { return points_[static_cast<size_t>(obs * dims + best_dim)]; };
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int64_t a, int64_t b) { return coord(a) < coord(b); });
  const float split = coord(order_[static_cast<size_t>(mid)]);
  // Left: [begin, mid) holds coordinates <= split; right: [mid, end) holds coordinates >= split.
  const int32_t left = build(begin, mid);
  const int32_t right = build(mid, end);
  Node& node = nodes_[static_cast<size_t>(id)];
  node.split_dim = best_dim;
  node.split_value = split;
  node.left = left;
  node.right = right;
  return id;
}

std::vector<Neighbor> ProjectedKdTree::knn_projected(const float* point, int k) const {
  LMB_CHECK(k >= 1, "ProjectedKdTree::knn: k " << k << " must be >= 1");
  const int dims = options_.dims;
  const size_t want = static_cast<size_t>(std::min<int64_t>(k, obs_.size()));
  // Max-heap on (squared distance, index): the worst kept neighbour on top.
  using Entry = std::pair<float, int64_t>;
  std::vector<Entry> heap;
  heap.reserve(want + 1);
  // Arya-Mount incremental search: off[d] is the query's offset from the current cell along d and
  // rect = sum off[d]^2 a lower bound on the squared distance of every point in the cell. The bound
  // is computed in double and shrunk by a relative 1e-5 and an absolute 1e-9 before pruning, far
  // more than the rounding of squared_distance (float, 16 terms: < 1e-6 relative), so a cell is
  // pruned only when all its points are strictly worse than the kept k-th: exact, ties included.
  std::vector<double> off(static_cast<size_t>(dims), 0.0);
  auto worse_than_kept = [&](double rect) {
    return heap.size() >= want && rect * (1.0 - 1e-5) - 1e-9 > static_cast<double>(heap.front().first);
  };
  auto visit = [&](auto&& self, int32_t node_id, double rect) -> void {
    const Node& node = nodes_[static_cast<size_t>(node_id)];
    if (node.split_dim < 0) {
      for (int64_t i = node.begin; i < node.end; ++i) {
        const int64_t obs = order_[static_cast<size_t>(i)];
        const Entry e{squared_distance(point, tree_points_.data() + i * dims, dims), obs};
        if (heap.size() < want) {
          heap.push_back(e);
          std::push_heap(heap.begin(), heap.end());
        } else if (e < heap.front()) {
          std::pop_heap(heap.begin(), heap.end());
          heap.back() = e;
          std::push_heap(heap.begin(), heap.end());
        }
      }
      return;
    }
    const double diff = static_cast<double>(point[node.split_dim]) - static_cast<double>(node.split_value);
    const int32_t near = diff < 0.0 ? node.left : node.right;
    const int32_t far = diff < 0.0 ? node.right : node.left;
    self(self, near, rect);
    double& o = off[static_cast<size_t>(node.split_dim)];
    const double old = o;
    const double far_rect = rect - old * old + diff * diff;
    if (worse_than_kept(far_rect)) return;
    o = std::abs(diff);
    self(self, far, far_rect);
    o = old;
  };
  visit(visit, 0, 0.0);
  std::sort_heap(heap.begin(), heap.end());
  std::vector<Neighbor> out;
  out.reserve(heap.size());
  for (const Entry& e : heap) out.push_back(Neighbor{e.second, std::sqrt(static_cast<double>(e.first))});
  return out;
}

std::vector<Neighbor> ProjectedKdTree::knn(const uint8_t* descriptor, int k) const {
  const Eigen::VectorXf p = project(descriptor);
  return knn_projected(p.data(), k);
}

std::vector<RankedCandidate> ProjectedKdTree::query(const uint8_t* descriptor, int k) const {
  return neighbors_to_candidates(knn(descriptor, k), obs_.landmark);
}

HammingValidationP1 hamming_validation_p1(const LandmarkMap& map, const TrainingSet& set) {
  std::vector<int64_t> validation;
  TrainingObservations all, landmarks;  // "landmark": the sample's class
  all.descriptor_bytes = landmarks.descriptor_bytes = map.descriptor_bytes;
  const size_t bytes = static_cast<size_t>(map.descriptor_bytes);
  for (int64_t s = 0; s < set.num_samples(); ++s) {
    if (!set.sample_copy.empty() && set.sample_copy[s] > 0) continue;  // an augmented copy: same descriptor
    if (set.sample_is_validation[s]) {
      validation.push_back(s);
      continue;
    }
    const uint8_t* d = map.descriptor(set.sample_keypoint[s]);
    for (TrainingObservations* o : {&all, &landmarks}) {
      if (o == &landmarks && set.sample_class[s] == set.background_class()) continue;
      o->descriptors.insert(o->descriptors.end(), d, d + bytes);
      o->landmark.push_back(set.sample_class[s]);
    }
  }
  HammingValidationP1 out;
  if (validation.empty()) return out;
  const auto p1 = [&](TrainingObservations observations) {
    if (observations.size() == 0) return 0.0;
    const BruteforceHamming index(std::move(observations));
    int64_t correct = 0;
    for (int64_t v : validation) {
      const std::vector<Neighbor> nn = index.knn(map.descriptor(set.sample_keypoint[v]), 1);
      correct += index.observations().landmark[static_cast<size_t>(nn[0].index)] == set.sample_class[v];
    }
    return static_cast<double>(correct) / static_cast<double>(validation.size());
  };
  out.all = p1(std::move(all));
  out.landmarks = p1(std::move(landmarks));
  return out;
}

}  // namespace lmb
