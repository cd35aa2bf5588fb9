#include "train/areas/area_split.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

constexpr uint64_t kPriorTag = 0x5052494F;  // "PRIO"

// A cell under construction: its box and its own landmarks.
struct Cell {
  AreaBox box;
  std::vector<landmark_t> landmarks;
};

class Splitter {
 public:
  Splitter(const LandmarkMap& map, const AreaSplitOptions& options, const std::vector<landmark_t>& eligible)
      : map_(map), options_(options), eligible_(eligible) {}

  std::vector<Area> run() {
    Cell root;
    root.landmarks = eligible_;
    std::vector<Area> areas;
    split(root, &areas);
    for (size_t i = 0; i < areas.size(); ++i) areas[i].id = static_cast<int32_t>(i);
    return areas;
  }

 private:
  const Eigen::Vector3d& position(landmark_t l) const { return map_.landmarks[l].position; }

  void split(const Cell& cell, std::vector<Area>* areas) {
    // Overlap: eligible landmarks outside the cell within `overlap` of it, nearest first.
    std::vector<std::pair<double, landmark_t>> overlap;
    if (options_.overlap > 0.0) {
      for (landmark_t l : eligible_) {
        const double d = cell.box.distance(position(l));
        if (d > 0.0 && d <= options_.overlap) overlap.emplace_back(d, l);
      }
    }
    const int64_t total = static_cast<int64_t>(cell.landmarks.size() + overlap.size());
    if (total > options_.max_classes) {
      Cell lower, upper;
      // As many parts as max_classes needs (overlap aside), so that areas come out nearly full
      // instead of halved to the next power of two.
      const int64_t parts = std::max<int64_t>(2, (total + options_.max_classes - 1) / options_.max_classes);
      if (halve(cell, static_cast<double>(parts / 2) / static_cast<double>(parts), &lower, &upper)) {
        split(lower, areas);
        split(upper, areas);
        return;
      }
    }
    Area area;
    area.cell = cell.box;
    area.landmarks = cell.landmarks;
    area.num_core = static_cast<int64_t>(cell.landmarks.size());
    if (area.num_core > options_.max_classes) {  // all at one place: keep the smaller ids
      area.landmarks.resize(static_cast<size_t>(options_.max_classes));
    }
    std::sort(overlap.begin(), overlap.end());
    for (const auto& [d, l] : overlap) {
      if (static_cast<int64_t>(area.landmarks.size()) >= options_.max_classes) break;
      area.landmarks.push_back(l);
    }
    area.num_truncated = total - static_cast<int64_t>(area.landmarks.size());
    std::sort(area.landmarks.begin(), area.landmarks.end());
    area.bounds.lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    area.bounds.hi = -area.bounds.lo;
    for (landmark_t l : area.landmarks) {
      area.bounds.lo = area.bounds.lo.cwiseMin(position(l));
      area.bounds.hi = area.bounds.hi.cwiseMax(position(l));
    }
    if (area.landmarks.empty()) area.bounds.lo = area.bounds.hi = Eigen::Vector3d::Zero();
    areas->push_back(std::move(area));
  }

  // Splits at the `fraction` quantile (0.5 = the median) of the cell's landmarks along their
  // widest axis (the 5%..95% quantile range; other axes in decreasing width when no split value
  // separates them there). False when they are all at one place.
  bool halve(const Cell& cell, double fraction, Cell* lower, Cell* upper) const {
    if (cell.landmarks.size() < 2) return false;
    // Width: between the 5% and 95% quantiles, so that a few stray points do not pick the axis;
    // then the full extent (an axis with only stray spread can still be split).
    Eigen::Vector3d width, extent;
    std::vector<double> coord(cell.landmarks.size());
    for (int axis = 0; axis < 3; ++axis) {
      for (size_t i = 0; i < coord.size(); ++i) coord[i] = position(cell.landmarks[i])[axis];
      std::sort(coord.begin(), coord.end());
      const size_t n = coord.size();
      width[axis] = coord[n - 1 - n / 20] - coord[n / 20];
      extent[axis] = coord[n - 1] - coord[0];
    }
    std::array<int, 3> axes{0, 1, 2};
    std::stable_sort(axes.begin(), axes.end(), [&](int a, int b) {
      if (width[a] != width[b]) return width[a] > width[b];
      return extent[a] > extent[b];
    });
    for (int axis : axes) {
      if (!(extent[axis] > 0.0)) continue;
      std::vector<landmark_t> order = cell.landmarks;
      std::sort(order.begin(), order.end(), [&](landmark_t a, landmark_t b) {
        if (position(a)[axis] != position(b)[axis]) return position(a)[axis] < position(b)[axis];
        return a < b;
      });
      // The split nearest the quantile between two distinct coordinates.
      const size_t n = order.size();
      const size_t target =
          std::clamp<size_t>(static_cast<size_t>(std::llround(fraction * static_cast<double>(n))), 1, n - 1);
      size_t best = 0;
      for (size_t d = 0; d < n && best == 0; ++d) {
        for (const size_t m : {target - d, target + d}) {
          if (m >= 1 && m < n && position(order[m - 1])[axis] < position(order[m])[axis]) {
            best = m;
            break;
          }
        }
      }
      if (best == 0) continue;
      const double threshold = 0.5 * (position(order[best - 1])[axis] + position(order[best])[axis]);
      *lower = Cell{cell.box, {}};
      *upper = Cell{cell.box, {}};
      lower->box.hi[axis] = threshold;
      upper->box.lo[axis] = threshold;
      for (landmark_t l : cell.landmarks) (position(l)[axis] < threshold ? lower : upper)->landmarks.push_back(l);
      return true;
    }
    return false;
  }

  const LandmarkMap& map_;
  const AreaSplitOptions& options_;
  const std::vector<landmark_t>& eligible_;  // ascending
};

}  // namespace

void AreaSplitOptions::check() const {
  LMB_CHECK(max_classes >= 1, "--max-classes " << max_classes << ": must be >= 1");
  LMB_CHECK(min_observations >= 1, "--min-observations " << min_observations << ": must be >= 1");
  LMB_CHECK(std::isfinite(overlap) && overlap >= 0.0, "--overlap " << overlap << ": must be finite and >= 0");
  LMB_CHECK(std::isfinite(reach) && reach >= 0.0, "--reach " << reach << ": must be finite and >= 0 (0 = automatic)");
}

double AreaBox::distance(const Eigen::Vector3d& p) const {
  double sq = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double d = p[a] < lo[a] ? lo[a] - p[a] : (p[a] > hi[a] ? p[a] - hi[a] : 0.0);
    sq += d * d;
  }
  return std::sqrt(sq);
}

std::vector<int32_t> map_observation_counts(const LandmarkMap& map) {
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  LMB_CHECK(static_cast<int64_t>(map.keypoint_landmark.size()) == num_keypoints,
            "map: keypoint_landmark has " << map.keypoint_landmark.size() << " entries for " << num_keypoints
                                          << " keypoints");
  std::vector<int32_t> counts(static_cast<size_t>(num_landmarks), 0);
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    LMB_CHECK(frame.first_keypoint >= 0 && frame.num_keypoints >= 0 &&
                  frame.first_keypoint + frame.num_keypoints <= num_keypoints,
              "map: frame " << f << " (" << frame.name << ") keypoint range out of bounds");
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      LMB_CHECK(l == kInvalidLandmarkId || (l >= 0 && l < num_landmarks),
                "map: keypoint " << k << " refers to landmark " << l << " of " << num_landmarks);
      if (l != kInvalidLandmarkId && !frame.is_query) ++counts[l];
    }
  }
  return counts;
}

double map_observation_distance(const LandmarkMap& map, double q) {
  std::vector<double> d;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    const Eigen::Vector3d c = f.cam_from_world.center();
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l != kInvalidLandmarkId) d.push_back((map.landmarks[l].position - c).norm());
    }
  }
  LMB_CHECK(!d.empty(), "map: no map frame observes a landmark");
  const size_t i = std::min(d.size() - 1, static_cast<size_t>(std::floor(q * static_cast<double>(d.size()))));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(i), d.end());
  return d[i];
}

AreaSplit split_map_into_areas(const LandmarkMap& map, const AreaSplitOptions& options) {
  options.check();
  const std::vector<int32_t> counts = map_observation_counts(map);
  AreaSplit split;
  split.options = options;
  std::vector<landmark_t> eligible;
  for (size_t l = 0; l < counts.size(); ++l) {
    if (counts[l] >= options.min_observations) eligible.push_back(static_cast<landmark_t>(l));
  }
  split.num_eligible = static_cast<int64_t>(eligible.size());
  LMB_CHECK(split.num_eligible > 0,
            "map: no landmark has at least " << options.min_observations << " map observations (--min-observations)");
  for (landmark_t l : eligible) {
    LMB_CHECK(map.landmarks[l].position.allFinite(), "map: landmark " << l << " has a non-finite position");
  }
  if (split.options.reach == 0.0) split.options.reach = map_observation_distance(map, 0.9);
  split.areas = Splitter(map, split.options, eligible).run();
  return split;
}

std::vector<int32_t> areas_near(const AreaSplit& split, const Eigen::Vector3d& position, double radius) {
  std::vector<int32_t> ids;
  for (const Area& a : split.areas) {
    if (a.cell.distance(position) <= radius) ids.push_back(a.id);
  }
  return ids;
}

std::vector<landmark_t> uncovered_landmarks(const LandmarkMap& map, const AreaSplit& split) {
  const std::vector<int32_t> counts = map_observation_counts(map);
  std::vector<uint8_t> covered(counts.size(), 0);
  for (const Area& a : split.areas) {
    for (landmark_t l : a.landmarks) covered[l] = 1;
  }
  std::vector<landmark_t> out;
  for (size_t l = 0; l < counts.size(); ++l) {
    if (counts[l] >= split.options.min_observations && !covered[l]) out.push_back(static_cast<landmark_t>(l));
  }
  return out;
}

Eigen::Vector3d prior_direction(uint64_t seed, int64_t frame) {
  // Uniform on the sphere: z uniform in [-1, 1), azimuth uniform.
  const double z = 2.0 * to_unit_double(counter_hash(seed, kPriorTag, static_cast<uint64_t>(frame), 0)) - 1.0;
  const double phi = 2.0 * M_PI * to_unit_double(counter_hash(seed, kPriorTag, static_cast<uint64_t>(frame), 1));
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
}

AreaCoverage query_coverage(const LandmarkMap& map, const AreaSplit& split, double prior_noise, uint64_t seed) {
  LMB_CHECK(std::isfinite(prior_noise) && prior_noise >= 0.0,
            "--prior-noise " << prior_noise << ": must be finite and >= 0");
  const size_t num_landmarks = map.landmarks.size();
  const std::vector<int32_t> counts = map_observation_counts(map);
  // Per landmark, the areas that hold it (sorted).
  std::vector<std::vector<int32_t>> landmark_areas(num_landmarks);
  for (const Area& a : split.areas) {
    for (landmark_t l : a.landmarks) {
      LMB_CHECK(l >= 0 && static_cast<size_t>(l) < num_landmarks,
                "areas: area " << a.id << " holds landmark " << l << " of a map with " << num_landmarks);
      landmark_areas[l].push_back(a.id);
    }
  }
  AreaCoverage cov;
  int64_t selected_total = 0;
  std::vector<int64_t> per_area(split.areas.size(), 0);
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& frame = map.frames[f];
    if (!frame.is_query) continue;
    const Eigen::Vector3d prior = frame.cam_from_world.center() + prior_noise * prior_direction(seed, f);
    const std::vector<int32_t> selected = areas_near(split, prior, prior_noise + split.options.reach);
    ++cov.num_query_frames;
    selected_total += static_cast<int64_t>(selected.size());
    cov.max_selected_areas = std::max(cov.max_selected_areas, static_cast<int32_t>(selected.size()));
    std::fill(per_area.begin(), per_area.end(), 0);
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l == kInvalidLandmarkId) continue;
      ++cov.num_keypoints;
      cov.num_eligible += counts[l] >= split.options.min_observations;
      bool any = false;
      for (int32_t a : landmark_areas[l]) {
        if (std::binary_search(selected.begin(), selected.end(), a)) {
          any = true;
          ++per_area[a];
        }
      }
      cov.num_covered_any += any;
    }
    int64_t best = 0;
    for (int64_t n : per_area) best = std::max(best, n);
    cov.num_covered_best += best;
  }
  cov.mean_selected_areas = cov.num_query_frames ? static_cast<double>(selected_total) / cov.num_query_frames : 0.0;
  return cov;
}

}  // namespace lmb
