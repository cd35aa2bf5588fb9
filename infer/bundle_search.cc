#include "infer/detail/bundle_search.h"

#include <algorithm>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>

#include "common/error.h"
#include "infer/detail/task_pool.h"

namespace lmb::detail {

namespace {

constexpr size_t kNone = std::numeric_limits<size_t>::max();

// One area's localization of the frame, or why its model could not be loaded.
struct AreaRun {
  std::shared_ptr<const Model> model;  // null when it could not be loaded
  std::string error;
  bool loaded_now = false;  // read from its file by this call
  LocalizeResult result;
};

// The verdict over the areas scored so far: each pose's support over their matches, the winner
// (an index into the scored areas), its rival and the bundle's evidence and confidence (-1
// without a calibration).
struct Verdict {
  size_t best = kNone;
  std::vector<int32_t> support;  // per scored area
  int32_t rival = 0;
  PoseEvidence evidence;
  double confidence = -1.0;
};

// One frame's search (search_areas): the frame, what the scored areas gave, the order and the stop.
class BundleSearch {
 public:
  BundleSearch(AreaBundle& bundle, const SearchPlan& plan, const Camera& camera, const std::vector<Keypoint>& keypoints,
               const uint8_t* descriptors, const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options,
               AreaWinner winner, TaskPool* pool)
      : bundle_(bundle),
        plan_(plan),
        camera_(camera),
        keypoints_(keypoints),
        descriptors_(descriptors),
        gravity_in_cam_(gravity_in_cam),
        options_(options),
        winner_(winner),
        pool_(pool),
        candidates_(keypoints.size()),
        calibrated_(bundle.calibrated()),
        confidence_stops_(calibrated_ && !bundle.calibration().saw_no_wrong_pose()),
        threshold_(!calibrated_                    ? -1.0
                   : options.min_confidence >= 0.0 ? options.min_confidence
                                                   : bundle.calibration().threshold) {
    std::vector<Eigen::Vector2d> pixels(keypoints.size());
    for (size_t k = 0; k < keypoints.size(); ++k) pixels[k] = Eigen::Vector2d(keypoints[k].x, keypoints[k].y);
    bearings_ = keypoint_bearings(camera, pixels);  // once: judged per area
  }

  BundleLocalizeResult run(std::chrono::steady_clock::time_point start);

 private:
  void run_area(int32_t id, AreaRun* run);
  AreaRun next_run(size_t next);
  void add_scored(int32_t id, AreaRun run);
  Verdict judge(size_t forced) const;
  bool passes_gate(const Verdict& v) const;
  void rank_by_view(size_t next, const Verdict& verdict);
  void finish(Verdict verdict);

  AreaBundle& bundle_;
  const SearchPlan& plan_;
  const Camera& camera_;
  const std::vector<Keypoint>& keypoints_;
  const uint8_t* descriptors_;
  const Eigen::Vector3d& gravity_in_cam_;
  const LocalizerOptions& options_;
  const AreaWinner winner_;
  TaskPool* pool_;
  std::mutex prepared_mutex_;
  std::shared_ptr<const PreparedFrame> prepared_;  // guarded by prepared_mutex_
  std::vector<Eigen::Vector3d> bearings_;
  // Every scored area's matches (per keypoint, distinct 3D points) and its result while it may win.
  std::vector<std::vector<Eigen::Vector3d>> candidates_;
  std::vector<LocalizeResult> posed_;  // per scored area with a pose: its result
  std::vector<size_t> posed_index_;    // per scored area: index into posed_, or kNone
  const bool calibrated_;
  // The bundle's confidence may stop a nearest-first search: a calibration that saw no wrong pose
  // (every pose it is 0.5, reported) would stop at the first area with any pose.
  const bool confidence_stops_;
  const double threshold_;
  std::vector<int32_t> order_;        // the search's order (re-ranked with the view prior)
  std::map<int32_t, AreaRun> ahead_;  // areas a wave ran that the order has not reached yet
  size_t ranked_by_ = kNone;          // the scored index whose pose's view ranked order_
  BundleLocalizeResult out_;
};

void BundleSearch::run_area(int32_t id, AreaRun* run) {
  // (`loaded_now` is exact for one caller at a time: another may load the same area meanwhile.)
  run->loaded_now = !bundle_.loaded(id);
  try {
    run->model = bundle_.model(id);
  } catch (const Error& e) {
    run->error = e.what();
    run->loaded_now = false;
    return;
  }
  // The frame's words, placed keypoints and context index: once for every area of one vocabulary
  // (all of a bundle's, as `lboost train --area` makes them), by the first area to need them.
  std::shared_ptr<const PreparedFrame> frame;
  {
    const std::lock_guard<std::mutex> lock(prepared_mutex_);
    if (prepared_ == nullptr) {
      prepared_ = std::make_shared<const PreparedFrame>(run->model, camera_, keypoints_, descriptors_, gravity_in_cam_);
    }
    if (prepared_->serves(*run->model)) frame = prepared_;
  }
  const Localizer localizer(run->model, options_);
  run->result = frame != nullptr ? localizer.localize(camera_, keypoints_, descriptors_, *frame, options_)
                                 : localizer.localize(camera_, keypoints_, descriptors_, gravity_in_cam_, options_);
}

// The run of order_[next]: taken from the areas run ahead, or run now in a wave with the next
// areas of the current order not yet run, one a thread.
AreaRun BundleSearch::next_run(size_t next) {
  auto found = ahead_.find(order_[next]);
  if (found == ahead_.end()) {
    const size_t threads = pool_ != nullptr ? static_cast<size_t>(pool_->threads()) : 1;
    std::vector<int32_t> wave{order_[next]};
    for (size_t j = next + 1; j < order_.size() && wave.size() < threads; ++j) {
      if (ahead_.count(order_[j]) == 0) wave.push_back(order_[j]);
    }
    std::vector<AreaRun> runs(wave.size());
    if (wave.size() == 1) {
      run_area(wave[0], &runs[0]);
    } else {
      std::vector<std::function<void()>> tasks;
      for (size_t i = 0; i < wave.size(); ++i) tasks.emplace_back([&, i] { run_area(wave[i], &runs[i]); });
      pool_->run(tasks);
    }
    for (size_t i = 0; i < wave.size(); ++i) ahead_.emplace(wave[i], std::move(runs[i]));
    found = ahead_.find(order_[next]);
  }
  AreaRun run = std::move(found->second);
  ahead_.erase(found);
  return run;
}

void BundleSearch::add_scored(int32_t id, AreaRun run) {
  LocalizeResult& r = run.result;
  out_.scored.push_back(id);
  out_.inliers.push_back(r.pose.success ? r.pose.num_inliers : 0);
  for (size_t i = 0; i < r.correspondence_keypoint.size(); ++i) {
    // A landmark that two overlapping areas both match to a keypoint is one candidate.
    std::vector<Eigen::Vector3d>& list = candidates_[static_cast<size_t>(r.correspondence_keypoint[i])];
    const Eigen::Vector3d& p = run.model->class_position(r.matches.matches[r.correspondence_match[i]].cls);
    if (std::find(list.begin(), list.end(), p) == list.end()) list.push_back(p);
  }
  posed_index_.push_back(r.pose.success ? posed_.size() : kNone);
  if (r.pose.success) posed_.push_back(std::move(r));
}

// The verdict over the areas scored so far; `forced`: that scored index wins, else the winner rule.
Verdict BundleSearch::judge(size_t forced) const {
  Verdict v;
  std::vector<Rigid3d> poses;
  for (const LocalizeResult& r : posed_) poses.push_back(r.pose.cam_from_world);
  const std::vector<int> support =
      count_explained_keypoints(camera_, bearings_, candidates_, poses, options_.pose.max_reprojection_error_px);
  v.support.assign(out_.scored.size(), 0);
  for (size_t i = 0; i < out_.scored.size(); ++i) {
    if (posed_index_[i] == kNone) continue;
    v.support[i] = support[posed_index_[i]];
    const auto key = [&](size_t j) {
      const int32_t rule = winner_ == AreaWinner::kSupport ? v.support[j] : 0;
      return std::make_tuple(rule, out_.inliers[j], -out_.scored[j]);
    };
    if (v.best == kNone || key(i) > key(v.best)) v.best = i;
  }
  if (forced != kNone) v.best = forced;
  if (v.best == kNone) return v;
  const Rigid3d winner_pose = poses[posed_index_[v.best]];
  const std::vector<int> rival = count_explained_keypoints(camera_, bearings_, candidates_, poses,
                                                           options_.pose.max_reprojection_error_px, &winner_pose);
  for (size_t j = 0; j < rival.size(); ++j) {
    if (j != posed_index_[v.best]) v.rival = std::max(v.rival, rival[j]);
  }
  PoseEvidence& e = v.evidence;
  e = posed_[posed_index_[v.best]].evidence;  // its area's inlier rank and spread
  e.num_keypoints = static_cast<int>(keypoints_.size());
  e.num_correspondences = static_cast<int>(
      std::count_if(candidates_.begin(), candidates_.end(), [](const auto& list) { return !list.empty(); }));
  e.num_inliers = v.support[v.best];
  e.runner_up_inliers = v.rival;
  if (calibrated_) v.confidence = bundle_.calibration().probability(e);
  return v;
}

// Whether the verdict's winner passes the gate: its pose lies within it and explains more keypoints
// than its rival (a look-alike pose as strong as another is no track to follow).
bool BundleSearch::passes_gate(const Verdict& v) const {
  return plan_.gate != nullptr && v.best != kNone && posed_index_[v.best] != kNone && v.support[v.best] > v.rival &&
         (posed_[posed_index_[v.best]].pose.cam_from_world.center() - plan_.gate->position).norm() <=
             plan_.gate->radius;
}

// The areas after order_[next] that see most of the verdict's winning pose's view next (an area
// that cannot load counts 0), then the nearest to the view prior, then the smaller id.
void BundleSearch::rank_by_view(size_t next, const Verdict& verdict) {
  ranked_by_ = verdict.best;
  const Rigid3d& pose = posed_[posed_index_[verdict.best]].pose.cam_from_world;
  std::vector<std::tuple<int32_t, double, int32_t>> rank;
  for (size_t j = next + 1; j < order_.size(); ++j) {
    int32_t visible = 0;
    try {
      visible = bundle_.visible_landmarks(order_[j], camera_, pose);
    } catch (const Error&) {
      visible = 0;
    }
    rank.emplace_back(-visible, bundle_.areas()[static_cast<size_t>(order_[j])].distance(plan_.view_prior->position),
                      order_[j]);
  }
  std::sort(rank.begin(), rank.end());
  for (size_t j = 0; j < rank.size(); ++j) order_[next + 1 + j] = std::get<2>(rank[j]);
}

void BundleSearch::finish(Verdict verdict) {
  out_.tracked = passes_gate(verdict);  // however the search ended
  out_.support = std::move(verdict.support);
  if (verdict.best == kNone) return;
  out_.area = out_.scored[verdict.best];
  out_.rival_support = verdict.rival;
  out_.evidence = verdict.evidence;
  out_.result = std::move(posed_[posed_index_[verdict.best]]);
  out_.localized = out_.result.localized;
  if (calibrated_) {
    out_.calibrated = true;
    out_.confidence = verdict.confidence;
    out_.confidence_threshold = threshold_;
    out_.localized = out_.confidence >= out_.confidence_threshold;
  }
}

BundleLocalizeResult BundleSearch::run(std::chrono::steady_clock::time_point start) {
  out_.selected = static_cast<int32_t>(plan_.order.size());
  order_ = plan_.order;
  Verdict verdict;
  bool verdict_current = false;  // `verdict` is over every area scored
  size_t forced = kNone;         // an area's own calibrated pose stopped the search: it wins
  bool stopped = false;
  for (size_t next = 0; next < order_.size() && !stopped; ++next) {
    AreaRun run = next_run(next);
    out_.loaded += run.loaded_now ? 1 : 0;
    if (!run.model) {
      out_.errors.push_back(std::move(run.error));
      continue;
    }
    const bool area_stops = !calibrated_ && plan_.nearest_first && run.result.calibrated && run.result.localized &&
                            !run.model->calibration().saw_no_wrong_pose();
    add_scored(order_[next], std::move(run));
    verdict_current = false;
    // With a gate, the gate and the bundle's calibration decide, not an area's own calibration.
    // (Fewer areas than gate_areas selected: the gate opens once all are scored.)
    const bool gate_open =
        plan_.gate != nullptr && out_.scored.size() >= std::min(static_cast<size_t>(plan_.gate_areas), order_.size());
    if (area_stops && plan_.gate == nullptr) {
      stopped = true;
      forced = out_.scored.size() - 1;
    } else if ((confidence_stops_ && plan_.nearest_first) || gate_open || plan_.view_prior != nullptr) {
      // A calibrated bundle stops at the first point where its verdict is localized; the motion
      // gate where the verdict's winner lies within it.
      verdict = judge(kNone);
      verdict_current = true;
      stopped = (gate_open && passes_gate(verdict)) ||
                (confidence_stops_ && plan_.nearest_first && verdict.best != kNone && verdict.confidence >= threshold_);
    }
    if (!stopped && plan_.view_prior != nullptr && verdict_current && verdict.best != kNone &&
        verdict.best != ranked_by_ && next + 2 < order_.size()) {
      rank_by_view(next, verdict);
    }
  }
  finish(verdict_current ? std::move(verdict) : judge(forced));
  out_.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return std::move(out_);
}

}  // namespace

BundleLocalizeResult search_areas(AreaBundle& bundle, const SearchPlan& plan, const Camera& camera,
                                  const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                  const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options,
                                  AreaWinner winner, TaskPool* pool, std::chrono::steady_clock::time_point start) {
  BundleSearch search(bundle, plan, camera, keypoints, descriptors, gravity_in_cam, options, winner, pool);
  return search.run(start);
}

void order_by_distance(const AreaBundle& bundle, const Eigen::Vector3d& position, std::vector<int32_t>* ids) {
  const std::vector<BundleArea>& areas = bundle.areas();
  std::stable_sort(ids->begin(), ids->end(), [&](int32_t a, int32_t b) {
    return areas[static_cast<size_t>(a)].distance(position) < areas[static_cast<size_t>(b)].distance(position);
  });
}

void check_search_options(AreaSearch search, AreaWinner winner, int area_threads, const char* where) {
  LMB_CHECK(search == AreaSearch::kNearestFirst || search == AreaSearch::kAll || search == AreaSearch::kWinnersView,
            where << ": unknown area search " << static_cast<int32_t>(search));
  LMB_CHECK(winner == AreaWinner::kSupport || winner == AreaWinner::kInliers,
            where << ": unknown area winner " << static_cast<int32_t>(winner));
  LMB_CHECK(area_threads >= 1 && area_threads <= 256,
            where << ": area_threads = " << area_threads << " must be in 1..256");
}

BundleLocalizeResult localize_in_bundle(AreaBundle& bundle, const Camera& camera,
                                        const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                        const Eigen::Vector3d& gravity_in_cam, const PositionPrior* prior,
                                        const LocalizerOptions& options, AreaSearch search, AreaWinner winner,
                                        int area_threads) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  check_search_options(search, winner, area_threads, "localize_in_bundle");
  SearchPlan plan;
  plan.order = bundle.select(prior);
  plan.nearest_first = prior != nullptr && search != AreaSearch::kAll;
  if (plan.nearest_first) order_by_distance(bundle, prior->position, &plan.order);
  plan.view_prior = plan.nearest_first && search == AreaSearch::kWinnersView ? prior : nullptr;
  std::unique_ptr<TaskPool> pool = area_threads > 1 ? std::make_unique<TaskPool>(area_threads) : nullptr;
  BundleLocalizeResult out =
      search_areas(bundle, plan, camera, keypoints, descriptors, gravity_in_cam, options, winner, pool.get(), start);
  out.prior_used = prior != nullptr;
  return out;
}

BundleLocalizeResult localize_in_areas(AreaBundle& bundle, const std::vector<int32_t>& ids, const Camera& camera,
                                       const std::vector<Keypoint>& keypoints, const uint8_t* descriptors,
                                       const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions& options,
                                       AreaWinner winner, int area_threads) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  check_search_options(AreaSearch::kAll, winner, area_threads, "localize_in_areas");
  for (size_t i = 0; i < ids.size(); ++i) {
    LMB_CHECK(ids[i] >= 0 && static_cast<size_t>(ids[i]) < bundle.areas().size(),
              "localize_in_areas: no area " << ids[i] << " (the bundle has " << bundle.areas().size() << ")");
    LMB_CHECK(std::find(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(i), ids[i]) ==
                  ids.begin() + static_cast<std::ptrdiff_t>(i),
              "localize_in_areas: area " << ids[i] << " is listed twice");
  }
  SearchPlan plan;
  plan.order = ids;
  std::unique_ptr<TaskPool> pool = area_threads > 1 ? std::make_unique<TaskPool>(area_threads) : nullptr;
  return search_areas(bundle, plan, camera, keypoints, descriptors, gravity_in_cam, options, winner, pool.get(), start);
}

}  // namespace lmb::detail
