#include "train/mapping/frame_pairs.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"

namespace lmb {

void PairOptions::check() const {
  LMB_CHECK(std::isfinite(max_center_distance) && max_center_distance >= 0,
            "pair options: max_center_distance must be finite and >= 0 (0 = automatic), got " << max_center_distance);
  LMB_CHECK(max_view_angle_deg > 0 && max_view_angle_deg <= 180,
            "pair options: max_view_angle_deg must be in (0, 180], got " << max_view_angle_deg);
  LMB_CHECK(max_pairs_per_frame >= 0, "pair options: max_pairs_per_frame must be >= 0");
  LMB_CHECK(sequence_neighbors >= 0, "pair options: sequence_neighbors must be >= 0");
}

namespace {

Eigen::Vector3d optical_axis(const Rigid3d& cam_from_world) {
  return cam_from_world.rotation.conjugate() * Eigen::Vector3d::UnitZ();
}

double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace

double automatic_pair_distance(const std::vector<PairFrame>& frames) {
  std::vector<Eigen::Vector3d> centers;
  for (const PairFrame& f : frames) {
    if (!f.is_query) centers.push_back(f.cam_from_world.center());
  }
  if (centers.size() < 2) return 0.0;
  std::vector<double> nearest;
  for (size_t i = 0; i < centers.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < centers.size(); ++j) {
      if (i != j) best = std::min(best, (centers[i] - centers[j]).norm());
    }
    nearest.push_back(best);
  }
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  return 8.0 * nearest[nearest.size() / 2];
}

std::vector<std::pair<int, int>> select_frame_pairs(const std::vector<PairFrame>& frames, const PairOptions& options) {
  options.check();
  const int n = static_cast<int>(frames.size());
  double max_distance = options.max_center_distance;
  if (max_distance <= 0) max_distance = automatic_pair_distance(frames);
  if (max_distance <= 0) max_distance = std::numeric_limits<double>::infinity();

  std::vector<Eigen::Vector3d> centers(n), axes(n);
  for (int i = 0; i < n; ++i) {
    centers[i] = frames[i].cam_from_world.center();
    axes[i] = optical_axis(frames[i].cam_from_world);
  }
  std::vector<std::pair<int, int>> pairs;
  auto add = [&](int i, int j) { pairs.emplace_back(std::min(i, j), std::max(i, j)); };

  struct Candidate {
    double cost;
    int index;
  };
  std::vector<Candidate> candidates;
  for (int i = 0; i < n; ++i) {
    candidates.clear();
    if (frames[i].outside) continue;
    for (int j = 0; j < n; ++j) {
      if (j == i || (frames[i].is_query && frames[j].is_query) || frames[j].outside) continue;
      const double distance = (centers[i] - centers[j]).norm();
      if (distance > max_distance) continue;
      const double angle = axis_angle_deg(axes[i], axes[j]);
      if (angle > options.max_view_angle_deg) continue;
      const double cost =
          (std::isfinite(max_distance) ? distance / max_distance : 0.0) + angle / options.max_view_angle_deg;
      candidates.push_back({cost, j});
    }
    const size_t keep = std::min(candidates.size(), static_cast<size_t>(options.max_pairs_per_frame));
    std::partial_sort(
        candidates.begin(), candidates.begin() + keep, candidates.end(),
        [](const Candidate& a, const Candidate& b) { return a.cost != b.cost ? a.cost < b.cost : a.index < b.index; });
    for (size_t c = 0; c < keep; ++c) add(i, candidates[c].index);
  }
  // Sequence neighbours within each map session.
  for (int i = 0; i < n; ++i) {
    if (frames[i].is_query) continue;
    int found = 0;
    for (int j = i + 1; j < n && found < options.sequence_neighbors; ++j) {
      if (frames[j].is_query || frames[j].session != frames[i].session) continue;
      add(i, j);
      ++found;
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

void OverlapPairOptions::check() const {
  LMB_CHECK(partners_per_frame >= 0, "overlap pair options: partners_per_frame must be >= 0");
  LMB_CHECK(std::isfinite(min_partner_separation_deg) && min_partner_separation_deg >= 0,
            "overlap pair options: min_partner_separation_deg must be finite and >= 0");
  LMB_CHECK(max_ray_angle_deg > 0 && max_ray_angle_deg <= 180,
            "overlap pair options: max_ray_angle_deg must be in (0, 180], got " << max_ray_angle_deg);
  LMB_CHECK(max_scale_change >= 1, "overlap pair options: max_scale_change must be >= 1");
  LMB_CHECK(min_shared_points >= 1, "overlap pair options: min_shared_points must be >= 1");
  LMB_CHECK(min_depth >= 0 && max_depth > min_depth,
            "overlap pair options: need 0 <= min_depth < max_depth, got " << min_depth << " and " << max_depth);
}

namespace {

// The scene points frame f sees (in front, between the depths, inside its image) and their depths.
void visible_points(const PairFrame& f, const ScenePoints& scene, const OverlapPairOptions& options,
                    std::vector<int>* points, std::vector<double>* depths) {
  points->clear();
  depths->clear();
  const Eigen::Matrix3d R = f.cam_from_world.rotation.toRotationMatrix();
  const double w = f.camera->width, h = f.camera->height;
  for (size_t p = 0; p < scene.position.size(); ++p) {
    const Eigen::Vector3d x = R * scene.position[p] + f.cam_from_world.translation;
    if (x.z() < options.min_depth || x.z() > options.max_depth) continue;
    Eigen::Vector2d pixel;
    if (!f.camera->project(x, &pixel) || !(pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() <= w && pixel.y() <= h))
      continue;
    points->push_back(static_cast<int>(p));
    depths->push_back(x.z());
  }
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

}  // namespace

std::vector<std::pair<int, int>> select_overlap_pairs(const std::vector<PairFrame>& frames, const ScenePoints& scene,
                                                      const OverlapPairOptions& options, OverlapPairStats* stats) {
  options.check();
  LMB_CHECK(scene.observers.size() == scene.position.size(), "overlap pairs: scene points without observer lists");
  const int n = static_cast<int>(frames.size());
  std::vector<Eigen::Vector3d> centers(n), axes(n);
  for (int i = 0; i < n; ++i) {
    LMB_CHECK(!frames[i].is_query || frames[i].outside || frames[i].camera != nullptr,
              "overlap pairs: query frame " << i << " has no camera");
    centers[i] = frames[i].cam_from_world.center();
    axes[i] = optical_axis(frames[i].cam_from_world);
  }
  for (const std::vector<int>& observers : scene.observers) {
    for (int j : observers) {
      LMB_CHECK(j >= 0 && j < n && !frames[j].is_query, "overlap pairs: observer " << j << " is not a map frame");
    }
  }
  const double cos_max_ray = std::cos(options.max_ray_angle_deg * M_PI / 180.0);
  std::vector<int> shared(n, 0), touched, visible, accepted;
  std::vector<double> depths, partner_distances;
  std::vector<std::pair<int, int>> pairs;
  OverlapPairStats s;
  for (int i = 0; i < n; ++i) {
    if (!frames[i].is_query || frames[i].outside) continue;
    // Shared points: seen by i (in its image and depth range) and observed by map frame j from a
    // similar direction and distance.
    visible_points(frames[i], scene, options, &visible, &depths);
    touched.clear();
    for (int p : visible) {
      const Eigen::Vector3d ray_i = scene.position[p] - centers[i];
      const double di = ray_i.norm();
      for (int j : scene.observers[p]) {
        const Eigen::Vector3d ray_j = scene.position[p] - centers[j];
        const double dj = ray_j.norm();
        if (ray_i.dot(ray_j) < cos_max_ray * di * dj) continue;
        if (di > options.max_scale_change * dj || dj > options.max_scale_change * di) continue;
        if (shared[j]++ == 0) touched.push_back(j);
      }
    }
    std::sort(touched.begin(), touched.end(),
              [&](int a, int b) { return shared[a] != shared[b] ? shared[a] > shared[b] : a < b; });
    // Greedy: most shared points first, each partner far enough (in view change) from those taken.
    const double depth = std::max(percentile(depths, 0.5), 1e-9);
    auto separation_deg = [&](int a, int b) {
      return axis_angle_deg(axes[a], axes[b]) + (centers[a] - centers[b]).norm() / depth * 180.0 / M_PI;
    };
    accepted.clear();
    for (int j : touched) {
      if (static_cast<int>(accepted.size()) >= options.partners_per_frame || shared[j] < options.min_shared_points)
        break;
      bool distinct = true;
      for (int a : accepted) distinct = distinct && separation_deg(j, a) >= options.min_partner_separation_deg;
      if (!distinct) continue;
      accepted.push_back(j);
      pairs.emplace_back(std::min(i, j), std::max(i, j));
      partner_distances.push_back((centers[i] - centers[j]).norm());
    }
    for (int j : touched) shared[j] = 0;
    (accepted.empty() ? s.query_frames_without : s.query_frames_with) += 1;
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  s.pairs = static_cast<int64_t>(pairs.size());
  if (s.query_frames_with > 0) s.mean_partners = static_cast<double>(pairs.size()) / s.query_frames_with;
  s.median_partner_distance = percentile(partner_distances, 0.5);
  s.p90_partner_distance = percentile(partner_distances, 0.9);
  s.max_partner_distance = percentile(partner_distances, 1.0);
  if (stats) *stats = s;
  return pairs;
}

}  // namespace lmb
