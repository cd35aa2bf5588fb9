#include "train/features/augmentation.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

namespace {

// Streams of the counter-based draws (the third key of counter_hash).
constexpr uint64_t kDropStream = 1;
constexpr uint64_t kRotationStream = 2;
constexpr uint64_t kPositionXStream = 4;  // and 5: the two uniforms of one Box-Muller draw
constexpr uint64_t kPositionYStream = 6;  // and 7
constexpr uint64_t kScaleStream = 8;      // and 9
// Frames and keypoints key different draws; a frame's key is offset so it never meets a keypoint's.
constexpr uint64_t kFrameKeyOffset = uint64_t{1} << 62;

double uniform_draw(uint64_t seed, uint64_t key, int32_t copy, uint64_t stream) {
  return to_unit_double(counter_hash(seed, key, static_cast<uint64_t>(copy), stream));
}

// A standard normal (Box-Muller) from the uniforms of streams `stream` and `stream + 1`.
double normal_draw(uint64_t seed, uint64_t key, int32_t copy, uint64_t stream) {
  const double u1 = 1.0 - uniform_draw(seed, key, copy, stream);  // (0, 1]
  const double u2 = uniform_draw(seed, key, copy, stream + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// The detector's repeatability test: is there a keypoint of the frame (ordered by x) within
// kRepeatRadius sizes of `at` whose size is within a factor kRepeatSizeRatio of `size`?
constexpr double kRepeatRadius = 0.5;
constexpr double kRepeatSizeRatio = 2.0;
constexpr double kChanceOffset = 4.0;

bool detected_near(const std::vector<Keypoint>& by_x, const Eigen::Vector2d& at, double size) {
  const double r = kRepeatRadius * size;
  auto it = std::lower_bound(by_x.begin(), by_x.end(), at.x() - r,
                             [](const Keypoint& k, double x) { return static_cast<double>(k.x) < x; });
  for (; it != by_x.end() && static_cast<double>(it->x) <= at.x() + r; ++it) {
    const double dx = it->x - at.x(), dy = it->y - at.y();
    if (dx * dx + dy * dy > r * r) continue;
    const double ratio = static_cast<double>(it->scale) / size;
    if (ratio >= 1.0 / kRepeatSizeRatio && ratio <= kRepeatSizeRatio) return true;
  }
  return false;
}

bool in_image(const Camera& camera, const Eigen::Vector2d& p) {
  return p.x() >= 0.0 && p.x() < camera.width && p.y() >= 0.0 && p.y() < camera.height;
}

double median_of(std::vector<double>* v) {
  if (v->empty()) return 0.0;
  const size_t mid = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(mid), v->end());
  return (*v)[mid];
}

}  // namespace

void AugmentNoise::check() const {
  LMB_CHECK(std::isfinite(dropout) && dropout >= 0.0 && dropout < 1.0,
            "augment: dropout " << dropout << " must be in [0, 1)");
  LMB_CHECK(std::isfinite(position_sigma) && position_sigma >= 0.0,
            "augment: position_sigma " << position_sigma << " must be finite and >= 0");
  LMB_CHECK(std::isfinite(scale_sigma) && scale_sigma >= 0.0,
            "augment: scale_sigma " << scale_sigma << " must be finite and >= 0");
  LMB_CHECK(std::isfinite(rotation_rad) && rotation_rad >= 0.0,
            "augment: rotation " << rotation_rad << " must be finite and >= 0");
}

std::string AugmentNoise::text() const {
  std::ostringstream os;
  os << "dropout " << dropout << ", position sigma " << position_sigma << " keypoint scales, log-scale sigma "
     << scale_sigma << ", rotation sigma " << rotation_rad * 180.0 / M_PI << " deg, seed " << seed;
  return os.str();
}

MapNoiseEstimate measure_map_noise(const LandmarkMap& map, int32_t max_frames) {
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  const frame_t num_frames = map.num_frames();
  // Per map frame: its tracks (landmark, metric size = keypoint size / focal length x depth, the
  // first keypoint per landmark), sorted by landmark, and its keypoints ordered by x.
  std::vector<std::vector<std::pair<landmark_t, double>>> tracks(static_cast<size_t>(num_frames));
  std::vector<std::vector<Keypoint>> by_x(static_cast<size_t>(num_frames));
  std::vector<std::vector<frame_t>> landmark_frames(static_cast<size_t>(num_landmarks));
  std::vector<frame_t> map_frames;
  MapNoiseEstimate out;
  std::vector<double> residuals;
  std::vector<std::vector<double>> track_logs(static_cast<size_t>(num_landmarks));
  for (frame_t f = 0; f < num_frames; ++f) {
    const MapFrame& fr = map.frames[f];
    if (fr.is_query) continue;
    map_frames.push_back(f);
    LMB_CHECK(fr.camera >= 0 && fr.camera < static_cast<camera_t>(map.cameras.size()),
              "augment: frame " << f << " camera " << fr.camera << " out of range");
    LMB_CHECK(fr.first_keypoint >= 0 && fr.num_keypoints >= 0 &&
                  fr.first_keypoint + fr.num_keypoints <= static_cast<int64_t>(map.keypoint_landmark.size()) &&
                  fr.first_keypoint + fr.num_keypoints <= static_cast<int64_t>(map.keypoints.size()),
              "augment: frame " << f << " keypoint range out of bounds");
    const Camera& camera = map.cameras[fr.camera];
    by_x[f].assign(map.keypoints.begin() + fr.first_keypoint,
                   map.keypoints.begin() + fr.first_keypoint + fr.num_keypoints);
    std::sort(by_x[f].begin(), by_x[f].end(), [](const Keypoint& a, const Keypoint& b) { return a.x < b.x; });
    for (int64_t k = fr.first_keypoint; k < fr.first_keypoint + fr.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      if (l == kInvalidLandmarkId) continue;
      LMB_CHECK(l >= 0 && l < num_landmarks, "augment: keypoint " << k << " landmark " << l << " out of range");
      landmark_frames[l].push_back(f);
      const Keypoint& kp = map.keypoints[k];
      const Eigen::Vector3d in_cam = fr.cam_from_world * map.landmarks[l].position;
      const double metric_size = static_cast<double>(kp.scale) / camera.mean_focal_length() * in_cam.z();
      tracks[f].emplace_back(l, metric_size);
      Eigen::Vector2d pixel;
      if (!(kp.scale > 0.f) || !std::isfinite(kp.scale) || !camera.project(in_cam, &pixel)) continue;
      const double r = (pixel - Eigen::Vector2d(kp.x, kp.y)).norm() / kp.scale;
      if (std::isfinite(r)) residuals.push_back(r);
      const double log_size = std::log(metric_size);
      if (std::isfinite(log_size)) track_logs[l].push_back(log_size);
    }
    std::stable_sort(tracks[f].begin(), tracks[f].end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    tracks[f].erase(std::unique(tracks[f].begin(), tracks[f].end(),
                                [](const auto& a, const auto& b) { return a.first == b.first; }),
                    tracks[f].end());
  }
  // Position: a 2D Gaussian's radius has median sigma * sqrt(2 ln 2).
  out.residuals = static_cast<int64_t>(residuals.size());
  out.position_sigma = median_of(&residuals) / std::sqrt(2.0 * std::log(2.0));
  // Scale: pooled within-track standard deviation of log(size x depth).
  double sum_sq = 0.0;
  int64_t dof = 0;
  for (const std::vector<double>& logs : track_logs) {
    if (logs.size() < 2) continue;
    double mean = 0.0;
    for (double v : logs) mean += v;
    mean /= static_cast<double>(logs.size());
    for (double v : logs) sum_sq += (v - mean) * (v - mean);
    dof += static_cast<int64_t>(logs.size()) - 1;
    out.track_observations += static_cast<int64_t>(logs.size());
  }
  out.scale_sigma = dof > 0 ? std::sqrt(sum_sq / static_cast<double>(dof)) : 0.0;

  // Re-observation rate and repeatability over covisible frame pairs from evenly spaced reference
  // frames.
  const int64_t num_map = static_cast<int64_t>(map_frames.size());
  const int64_t refs = std::min<int64_t>(num_map, std::max<int32_t>(max_frames, 1));
  int64_t observed = 0, repeated = 0, by_chance = 0;
  std::vector<uint8_t> seen(static_cast<size_t>(num_frames), 0);
  std::vector<frame_t> covisible;
  for (int64_t i = 0; i < refs; ++i) {
    const frame_t f = map_frames[static_cast<size_t>(i * num_map / refs)];
    covisible.clear();
    for (const auto& track : tracks[f]) {
      for (frame_t g : landmark_frames[track.first]) {
        if (g == f || seen[g]) continue;
        seen[g] = 1;
        covisible.push_back(g);
      }
    }
    for (frame_t g : covisible) {
      seen[g] = 0;
      const MapFrame& fg = map.frames[g];
      const Camera& camera = map.cameras[fg.camera];
      const std::vector<std::pair<landmark_t, double>>& in_g = tracks[g];
      for (const auto& [l, metric_size] : tracks[f]) {
        const Eigen::Vector3d in_g_cam = fg.cam_from_world * map.landmarks[l].position;
        Eigen::Vector2d pixel;
        if (!camera.project(in_g_cam, &pixel)) continue;
        if (!in_image(camera, pixel)) continue;
        ++out.projected;
        const auto it =
            std::lower_bound(in_g.begin(), in_g.end(), l, [](const auto& t, landmark_t x) { return t.first < x; });
        observed += it != in_g.end() && it->first == l;
        // The size the keypoint would have in g (size x depth / focal length is constant along a track).
        const double size_g = metric_size * camera.mean_focal_length() / in_g_cam.z();
        if (!(size_g > 0.0) || !std::isfinite(size_g)) continue;
        // Chance: the same test a few sizes to the side (where the landmark is not).
        const Eigen::Vector2d aside = pixel + Eigen::Vector2d(kChanceOffset * size_g, 0.0);
        if (!in_image(camera, aside)) continue;
        ++out.repeat_tests;
        repeated += detected_near(by_x[g], pixel, size_g);
        by_chance += detected_near(by_x[g], aside, size_g);
      }
    }
  }
  out.reobservation_rate = out.projected > 0 ? static_cast<double>(observed) / static_cast<double>(out.projected) : 1.0;
  if (out.repeat_tests > 0) {
    const double n = static_cast<double>(out.repeat_tests);
    const double hit = static_cast<double>(repeated) / n, chance = static_cast<double>(by_chance) / n;
    out.chance_rate = chance;
    out.repeatability = chance < 1.0 ? std::clamp((hit - chance) / (1.0 - chance), 0.0, 1.0) : 0.0;
  }
  return out;
}

bool augmented_keypoint_kept(const AugmentNoise& noise, int64_t keypoint, int32_t copy) {
  return noise.dropout <= 0.0 ||
         uniform_draw(noise.seed, static_cast<uint64_t>(keypoint), copy, kDropStream) >= noise.dropout;
}

FrameKeypoints augmented_frame(const FrameKeypoints& frame, frame_t frame_id, int64_t first_keypoint,
                               const AugmentNoise& noise, int32_t copy, std::vector<int32_t>* index_in_copy) {
  LMB_CHECK(copy >= 1, "augment: copy " << copy << " must be >= 1");
  const int32_t n = frame.size();
  const double angle =
      noise.rotation_rad > 0.0
          ? noise.rotation_rad *
                normal_draw(noise.seed, kFrameKeyOffset + static_cast<uint64_t>(frame_id), copy, kRotationStream)
          : 0.0;
  const double c = std::cos(angle), s = std::sin(angle);
  FrameKeypoints out;
  index_in_copy->assign(static_cast<size_t>(n), -1);
  for (int32_t i = 0; i < n; ++i) {
    const uint64_t key = static_cast<uint64_t>(first_keypoint + i);
    if (!augmented_keypoint_kept(noise, first_keypoint + i, copy)) continue;
    double x = frame.x[i], y = frame.y[i], scale = frame.scale[i];
    if (angle != 0.0) {
      const double rx = c * x - s * y;
      y = s * x + c * y;
      x = rx;
    }
    if (noise.position_sigma > 0.0) {
      x += noise.position_sigma * scale * normal_draw(noise.seed, key, copy, kPositionXStream);
      y += noise.position_sigma * scale * normal_draw(noise.seed, key, copy, kPositionYStream);
    }
    if (noise.scale_sigma > 0.0)
      scale *= std::exp(noise.scale_sigma * normal_draw(noise.seed, key, copy, kScaleStream));
    (*index_in_copy)[static_cast<size_t>(i)] = out.size();
    out.x.push_back(static_cast<float>(x));
    out.y.push_back(static_cast<float>(y));
    out.scale.push_back(static_cast<float>(scale));
    out.word.push_back(frame.word[i]);
  }
  return out;
}

}  // namespace lmb
