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

}  // namespace lmb
