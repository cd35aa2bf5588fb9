#include "train/mapping/guided_matching.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

void MatchingOptions::check() const {
  // The grid walk (16-pixel cells, 3x3 neighbourhoods every half cell) covers 12 pixels around the segment.
  LMB_CHECK(epipolar_threshold_px > 0 && epipolar_threshold_px <= 12,
            "matching options: epipolar_threshold_px must be in (0, 12], got " << epipolar_threshold_px);
  LMB_CHECK(min_depth > 0 && max_depth > min_depth,
            "matching options: need 0 < min_depth < max_depth, got " << min_depth << ", " << max_depth);
  LMB_CHECK(max_hamming_fraction > 0 && max_hamming_fraction <= 1,
            "matching options: max_hamming_fraction must be in (0, 1]");
  LMB_CHECK(ratio > 0 && ratio <= 1, "matching options: ratio must be in (0, 1]");
  LMB_CHECK(std::isfinite(max_scale_change), "matching options: max_scale_change must be finite");
}

MatchingFrame::MatchingFrame(const Camera& camera, const Rigid3d& cam_from_world,
                             const std::vector<Keypoint>& keypoints, const uint8_t* descriptors, int descriptor_bytes)
    : camera_(&camera),
      cam_from_world_(cam_from_world),
      focal_(camera.mean_focal_length()),
      descriptors_(descriptors),
      descriptor_bytes_(descriptor_bytes) {
  normalized_.reserve(keypoints.size());
  scale_.reserve(keypoints.size());
  for (const Keypoint& k : keypoints) {
    normalized_.push_back(camera.cam_from_img(Eigen::Vector2d(k.x, k.y)));
    scale_.push_back(k.scale);
  }
  // Cells of 16 pixels; the grid spans the keypoints' bounding box.
  cell_size_ = 16.0 / focal_;
  double max_x = 0, max_y = 0;
  min_x_ = min_y_ = 0;
  if (!normalized_.empty()) {
    min_x_ = max_x = normalized_[0].x();
    min_y_ = max_y = normalized_[0].y();
    for (const auto& p : normalized_) {
      min_x_ = std::min(min_x_, p.x());
      max_x = std::max(max_x, p.x());
      min_y_ = std::min(min_y_, p.y());
      max_y = std::max(max_y, p.y());
    }
  }
  cells_x_ = static_cast<int>((max_x - min_x_) / cell_size_) + 1;
  cells_y_ = static_cast<int>((max_y - min_y_) / cell_size_) + 1;
  cell_start_.assign(static_cast<size_t>(cells_x_) * cells_y_ + 1, 0);
  std::vector<int> cell_of(normalized_.size());
  for (size_t i = 0; i < normalized_.size(); ++i) {
    const int cx = std::min(cells_x_ - 1, static_cast<int>((normalized_[i].x() - min_x_) / cell_size_));
    const int cy = std::min(cells_y_ - 1, static_cast<int>((normalized_[i].y() - min_y_) / cell_size_));
    cell_of[i] = cy * cells_x_ + cx;
    ++cell_start_[cell_of[i] + 1];
  }
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(normalized_.size());
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (size_t i = 0; i < normalized_.size(); ++i) cell_items_[fill[cell_of[i]]++] = static_cast<int>(i);
}

GuidedMatcher::GuidedMatcher(const MatchingOptions& options) : options_(options) { options_.check(); }

namespace {

// Liang-Barsky clipping of segment p0-p1 to a rectangle; false when it misses the rectangle.
bool clip_segment(Eigen::Vector2d* p0, Eigen::Vector2d* p1, double x0, double y0, double x1, double y1) {
  const Eigen::Vector2d d = *p1 - *p0;
  double t0 = 0, t1 = 1;
  const double p[4] = {-d.x(), d.x(), -d.y(), d.y()};
  const double q[4] = {p0->x() - x0, x1 - p0->x(), p0->y() - y0, y1 - p0->y()};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    if (t0 > t1) return false;
  }
  const Eigen::Vector2d start = *p0 + t0 * d;
  *p1 = *p0 + t1 * d;
  *p0 = start;
  return true;
}

double point_segment_distance(const Eigen::Vector2d& q, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  double t = len2 > 0 ? (q - a).dot(ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (q - (a + t * ab)).norm();
}

}  // namespace

void GuidedMatcher::match_one_way(const MatchingFrame& from, const MatchingFrame& to, std::vector<int>* best,
                                  std::vector<int>* best_distance) {
  const int n = from.num_keypoints();
  best->assign(n, -1);
  best_distance->assign(n, std::numeric_limits<int>::max());
  if (n == 0 || to.num_keypoints() == 0) return;
  assert(from.descriptor_bytes_ == to.descriptor_bytes_);
  const int bytes = from.descriptor_bytes_;
  const int max_hamming = static_cast<int>(options_.max_hamming_fraction * 8 * bytes);
  const Rigid3d to_from_from = to.cam_from_world_ * from.cam_from_world_.inverse();
  const Eigen::Matrix3d R = to_from_from.rotation.toRotationMatrix();
  const Eigen::Vector3d& t = to_from_from.translation;
  const double threshold = options_.epipolar_threshold_px / to.focal_;
  const double margin = threshold;
  const double gx0 = to.min_x_ - margin, gy0 = to.min_y_ - margin;
  const double gx1 = to.min_x_ + to.cells_x_ * to.cell_size_ + margin;
  const double gy1 = to.min_y_ + to.cells_y_ * to.cell_size_ + margin;
  if (stamp_.size() < static_cast<size_t>(to.num_keypoints())) stamp_.assign(to.num_keypoints(), 0);

  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& r = from.normalized_[i];
    const Eigen::Vector3d v = R * Eigen::Vector3d(r.x(), r.y(), 1.0);
    // Depth range along the ray (z in `from`) that also keeps z in `to` within [min, max].
    double d0 = options_.min_depth, d1 = options_.max_depth;
    if (std::abs(v.z()) < 1e-12) {
      if (t.z() < options_.min_depth || t.z() > options_.max_depth) continue;
    } else {
      double a = (options_.min_depth - t.z()) / v.z();
      double b = (options_.max_depth - t.z()) / v.z();
      if (a > b) std::swap(a, b);
      d0 = std::max(d0, a);
      d1 = std::min(d1, b);
    }
    if (!(d0 < d1)) continue;
    const Eigen::Vector3d x0 = d0 * v + t, x1 = d1 * v + t;
    Eigen::Vector2d p0 = x0.head<2>() / x0.z(), p1 = x1.head<2>() / x1.z();
    if (!clip_segment(&p0, &p1, gx0, gy0, gx1, gy1)) continue;

    if (++stamp_value_ == 0) {
      std::fill(stamp_.begin(), stamp_.end(), 0);
      stamp_value_ = 1;
    }
    const uint8_t* desc = from.descriptors_ + static_cast<size_t>(i) * bytes;
    int best1 = std::numeric_limits<int>::max(), best2 = std::numeric_limits<int>::max(), best_index = -1;
    auto consider = [&](int j) {
      const Eigen::Vector2d& q = to.normalized_[j];
      if (point_segment_distance(q, p0, p1) > threshold) return;
      // Depth of the ray point that projects onto q (least squares in the `to` image plane).
      const Eigen::Vector2d w = q * v.z() - v.head<2>();
      const Eigen::Vector2d u = t.head<2>() - q * t.z();
      const double w2 = w.squaredNorm();
      if (w2 > 1e-18) {
        const double depth = w.dot(u) / w2;
        const double depth_to = depth * v.z() + t.z();
        if (depth < options_.min_depth || depth > options_.max_depth || depth_to < options_.min_depth ||
            depth_to > options_.max_depth) {
          return;
        }
        if (options_.max_scale_change > 0 && from.scale_[i] > 0 && to.scale_[j] > 0) {
          const double predicted = from.scale_[i] * (to.focal_ / from.focal_) * (depth / depth_to);
          const double change = to.scale_[j] / predicted;
          if (change > options_.max_scale_change || change * options_.max_scale_change < 1.0) return;
        }
      }
      const int dist = hamming_distance(desc, to.descriptors_ + static_cast<size_t>(j) * bytes, bytes);
      if (dist < best1) {
        best2 = best1;
        best1 = dist;
        best_index = j;
      } else if (dist < best2) {
        best2 = dist;
      }
    };
    if (options_.exhaustive_search) {
      for (int j = 0; j < to.num_keypoints(); ++j) consider(j);
    } else {
      const double length = (p1 - p0).norm();
      const int steps = static_cast<int>(length / (0.5 * to.cell_size_)) + 1;
      int last_cx = -100, last_cy = -100;
      for (int s = 0; s <= steps; ++s) {
        const Eigen::Vector2d p = p0 + (p1 - p0) * (static_cast<double>(s) / steps);
        const int cx = static_cast<int>(std::floor((p.x() - to.min_x_) / to.cell_size_));
        const int cy = static_cast<int>(std::floor((p.y() - to.min_y_) / to.cell_size_));
        if (cx == last_cx && cy == last_cy) continue;
        last_cx = cx;
        last_cy = cy;
        for (int yy = std::max(0, cy - 1); yy <= std::min(to.cells_y_ - 1, cy + 1); ++yy) {
          for (int xx = std::max(0, cx - 1); xx <= std::min(to.cells_x_ - 1, cx + 1); ++xx) {
            const int cell = yy * to.cells_x_ + xx;
            for (int c = to.cell_start_[cell]; c < to.cell_start_[cell + 1]; ++c) {
              const int j = to.cell_items_[c];
              if (stamp_[j] == stamp_value_) continue;
              stamp_[j] = stamp_value_;
              consider(j);
            }
          }
        }
      }
    }
    if (best_index < 0 || best1 > max_hamming) continue;
    if (best2 != std::numeric_limits<int>::max() && !(best1 < options_.ratio * best2)) continue;
    (*best)[i] = best_index;
    (*best_distance)[i] = best1;
  }
}

std::vector<Match> GuidedMatcher::match(const MatchingFrame& a, const MatchingFrame& b) {
  match_one_way(a, b, &best_ab_, &dist_ab_);
  match_one_way(b, a, &best_ba_, &dist_ba_);
  std::vector<Match> matches;
  for (int i = 0; i < a.num_keypoints(); ++i) {
    const int j = best_ab_[i];
    if (j >= 0 && best_ba_[j] == i) matches.push_back(Match{i, j, dist_ab_[i]});
  }
  return matches;
}

}  // namespace lmb
