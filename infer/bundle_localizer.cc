#include "infer/bundle_localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>

#include "common/error.h"
#include "infer/detail/bundle_search.h"
#include "infer/detail/task_pool.h"

namespace lmb {

void BundleLocalizerOptions::check() const {
  localizer.check();
  LMB_CHECK(std::isfinite(tracking_radius) && tracking_radius >= 0.0,
            "bundle localizer options: tracking_radius = " << tracking_radius << " must be finite and >= 0");
  detail::check_search_options(search, winner, area_threads, "bundle localizer options");
  LMB_CHECK(tracking_areas >= 1 && tracking_areas <= 256,
            "bundle localizer options: tracking_areas = " << tracking_areas << " must be in 1..256");
}

BundleLocalizer::BundleLocalizer(std::shared_ptr<AreaBundle> bundle, const BundleLocalizerOptions& options)
    : bundle_(std::move(bundle)), options_(options) {
  LMB_CHECK(bundle_ != nullptr, "bundle localizer: null bundle");
  set_options(options);
}

void BundleLocalizer::set_options(const BundleLocalizerOptions& options) {
  options.check();
  if (options.area_threads == 1) {
    pool_.reset();
  } else if (pool_ == nullptr || pool_->threads() != options.area_threads) {
    pool_ = std::make_shared<detail::TaskPool>(options.area_threads);
  }
  options_ = options;
  if (bundle_->calibrated() && bundle_->walk_calibration()) {
    PoseCalibration frame = bundle_->calibration();
    if (options.localizer.min_confidence >= 0.0) frame.threshold = options.localizer.min_confidence;
    if (!walk_ || walk_frame_threshold_ != frame.threshold) {
      walk_.emplace(frame, bundle_->walk_calibration());
      walk_frame_threshold_ = frame.threshold;
    }
  }
}

void BundleLocalizer::reset_tracking() {
  set_last_pose(std::nullopt);
  if (walk_) walk_->reset();
}

BundleLocalizeResult BundleLocalizer::localize(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                               const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                               const PositionPrior* prior) const {
  const auto start = std::chrono::steady_clock::now();
  detail::SearchPlan plan;
  plan.order = bundle_->select(prior);
  plan.nearest_first = prior != nullptr && options_.search != AreaSearch::kAll;
  if (plan.nearest_first) detail::order_by_distance(*bundle_, prior->position, &plan.order);
  plan.view_prior = plan.nearest_first && options_.search == AreaSearch::kWinnersView ? prior : nullptr;
  BundleLocalizeResult out = detail::search_areas(*bundle_, plan, camera, keypoints, descriptors, gravity_in_cam,
                                                  options_.localizer, options_.winner, pool_.get(), start);
  out.prior_used = prior != nullptr;
  return out;
}

BundleLocalizeResult BundleLocalizer::localize_in(const std::vector<int32_t>& ids, const Camera& camera,
                                                  const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                                  const Eigen::Vector3d& gravity_in_cam) const {
  return detail::localize_in_areas(*bundle_, ids, camera, keypoints, descriptors, gravity_in_cam, options_.localizer,
                                   options_.winner, options_.area_threads);
}

BundleLocalizeResult BundleLocalizer::track(const Camera& camera, const std::vector<Keypoint>& keypoints,
                                            const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam,
                                            const PositionPrior* relocalization_prior) {
  const auto start = std::chrono::steady_clock::now();
  // A bad relocalization prior is an error on every frame, not only on the frames that relocalize.
  if (relocalization_prior != nullptr) relocalization_prior->check();
  // A pose to track from: one within the motion gate of the last tracked pose, or with a calibrated
  // bundle one it reports localized (a wrong pose must not become the next prior), else any winning pose.
  const auto trusted = [](const BundleLocalizeResult& x) { return x.calibrated ? x.localized : x.area >= 0; };
  BundleLocalizeResult r;
  bool done = false;
  PositionPrior prior;  // with a last position: the tracked areas' prior and the motion gate
  if (last_position_) {
    prior.position = *last_position_;
    // The camera moves at most tracking_radius a frame: after frames without a tracked pose, further.
    prior.radius = options_.tracking_radius * static_cast<double>(1 + frames_since_pose_);
    const bool nearest_first = options_.search != AreaSearch::kAll;
    std::vector<int32_t> selected = bundle_->select(&prior);
    const int64_t loads_before = bundle_->loads();
    if (nearest_first) {
      // The areas that see most of the last pose's view first (by a sample of their landmarks), then
      // the nearest, then the smaller id. An area that cannot load counts 0 (scoring reports it).
      std::vector<std::tuple<int32_t, double, int32_t>> order;
      for (int32_t id : selected) {
        int32_t visible = 0;
        if (last_pose_) {
          try {
            visible = bundle_->visible_landmarks(id, camera, *last_pose_);
          } catch (const Error&) {
            visible = 0;
          }
        }
        order.emplace_back(-visible, bundle_->areas()[static_cast<size_t>(id)].distance(prior.position), id);
      }
      std::sort(order.begin(), order.end());
      for (size_t i = 0; i < order.size(); ++i) selected[i] = std::get<2>(order[i]);
    }
    const int32_t ranked_loads = static_cast<int32_t>(bundle_->loads() - loads_before);
    detail::SearchPlan plan;
    plan.order = std::move(selected);
    plan.nearest_first = nearest_first;
    plan.gate = nearest_first ? &prior : nullptr;
    plan.gate_areas = options_.tracking_areas;
    r = detail::search_areas(*bundle_, plan, camera, keypoints, descriptors, gravity_in_cam, options_.localizer,
                             options_.winner, pool_.get(), start);
    r.loaded += ranked_loads;
    r.prior_used = true;
    done = r.tracked || trusted(r) || !options_.relocalize_without_prior;
  }
  if (!done) {
    const int32_t loaded = r.loaded;
    std::vector<std::string> errors = std::move(r.errors);
    // Relocalization: the areas `relocalization_prior` selects, nearest first, or every area. With a
    // last pose, a winner inside its gate is tracked too (judged once all are scored, so the gate
    // does not stop the search early), e.g. the right pose after a lost frame.
    detail::SearchPlan plan;
    plan.order = bundle_->select(relocalization_prior);
    plan.nearest_first = relocalization_prior != nullptr && options_.search != AreaSearch::kAll;
    if (plan.nearest_first) detail::order_by_distance(*bundle_, relocalization_prior->position, &plan.order);
    plan.gate = last_position_ ? &prior : nullptr;
    plan.gate_areas = std::max(1, static_cast<int>(plan.order.size()));
    plan.view_prior =
        plan.nearest_first && options_.search == AreaSearch::kWinnersView ? relocalization_prior : nullptr;
    r = detail::search_areas(*bundle_, plan, camera, keypoints, descriptors, gravity_in_cam, options_.localizer,
                             options_.winner, pool_.get(), start);
    // The failed tracking attempt's time and loads count too.
    r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    r.loaded += loaded;
    for (std::string& e : r.errors) {
      if (std::find(errors.begin(), errors.end(), e) == errors.end()) errors.push_back(std::move(e));
    }
    r.errors = std::move(errors);
  }
  r.frame_localized = r.localized;
  const bool frame_trusted = trusted(r);
  if (walk_) {
    r.walk = walk_->update(r.area >= 0, r.result.pose.cam_from_world, r.evidence);
    r.walk_judged = true;
    r.localized = r.walk.localized;
  }
  // The next frame's prior: a gated pose, or one that is reported (by the walk's verdict when the
  // bundle has a walk calibration: a pose the walk refuses does not move the search).
  if (r.tracked || (walk_ ? r.localized : frame_trusted)) {
    set_last_pose(r.result.pose.cam_from_world);
  } else if (last_position_) {
    ++frames_since_pose_;
  }
  return r;
}

void BundleLocalizer::set_last_pose(const std::optional<Rigid3d>& cam_from_world) {
  last_pose_ = cam_from_world;
  last_position_.reset();
  frames_since_pose_ = 0;
  if (cam_from_world) last_position_ = cam_from_world->center();
}

}  // namespace lmb
