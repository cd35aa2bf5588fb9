#include "infer/c_api.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "common/error.h"
#include "infer/bundle_localizer.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/version.h"
#include "infer/walk_confidence.h"

struct lmb_model {
  std::shared_ptr<const lmb::Model> model;
};

struct lmb_walk {
  std::shared_ptr<const lmb::Model> model;
  lmb::WalkTracker tracker;
};

struct lmb_bundle {
  std::shared_ptr<lmb::AreaBundle> bundle;
  std::unique_ptr<lmb::BundleLocalizer> tracker;                      // lmb_bundle_track's state
  int tracking_areas = lmb::BundleLocalizerOptions{}.tracking_areas;  // lmb_bundle_set_tracking_areas
  int last_tracked = 0;  // the last lmb_bundle_track call's pose passed the motion gate
};

namespace {

thread_local std::string last_error;

lmb_status fail(lmb_status status, const std::string& message) {
  last_error = message;
  return status;
}

// Runs f, turning every exception into a status and the thread's last error.
template <class F>
lmb_status guarded(lmb_status error_status, const char* function, F&& f) {
  try {
    return f();
  } catch (const lmb::Error& e) {
    return fail(error_status, std::string(function) + ": " + e.what());
  } catch (const std::bad_alloc&) {
    return fail(LMB_ERROR_OUT_OF_MEMORY, std::string(function) + ": out of memory");
  } catch (const std::exception& e) {
    return fail(LMB_ERROR_INTERNAL, std::string(function) + ": " + e.what());
  } catch (...) {
    return fail(LMB_ERROR_INTERNAL, std::string(function) + ": unknown error");
  }
}

}  // namespace

extern "C" {

const char* lmb_last_error(void) { return last_error.c_str(); }

namespace {
// sizeof(lmb_localize_options) of its first version (struct_size .. seed): every later version
// only appends fields.
constexpr size_t kFirstOptionsSize = offsetof(lmb_localize_options, seed) + sizeof(uint64_t);

// The caller's options (its struct_size bytes of them, the defaults of the fields a shorter, older
// struct does not have; NULL: all defaults) as the Localizer's. Throws lmb::Error.
lmb::LocalizerOptions to_localizer_options(const lmb_localize_options* options) {
  lmb_localize_options o;
  lmb_localize_options_init(&o);
  if (options != nullptr) {
    LMB_CHECK(options->struct_size >= kFirstOptionsSize,
              "options->struct_size = " << options->struct_size << " (call lmb_localize_options_init first)");
    std::memcpy(&o, options, std::min(options->struct_size, sizeof(o)));
    o.struct_size = sizeof(o);
  }
  lmb::LocalizerOptions lo;
  lo.classifier.top_k = o.top_k;
  lo.classifier.use_inverted_file = o.use_inverted_file != 0;
  lo.classifier.min_margin = o.min_margin;
  lo.pose_top_k = o.pose_top_k;
  lo.max_correspondences = o.max_correspondences;
  lo.pose.max_iterations = o.ransac_iterations;
  lo.pose.max_reprojection_error_px = o.max_reprojection_error_px;
  lo.pose.min_inliers = o.min_inliers;
  lo.pose.seed = o.seed;
  lo.classifier.inverted_file_words = o.inverted_file_words;
  lo.check();
  return lo;
}

// The camera and keypoints of a C call in C++ form (the arguments checked for NULL by the caller).
lmb::Camera to_camera(const lmb_camera& camera) {
  lmb::Camera cam;
  cam.model = lmb::camera_model_from_id(camera.model);
  cam.width = camera.width;
  cam.height = camera.height;
  cam.params.assign(camera.params, camera.params + camera.num_params);
  return cam;
}

std::vector<lmb::Keypoint> to_keypoints(const lmb_keypoint* keypoints, int n) {
  std::vector<lmb::Keypoint> kps(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    kps[i].x = keypoints[i].x;
    kps[i].y = keypoints[i].y;
    kps[i].scale = keypoints[i].size;
    kps[i].angle = keypoints[i].angle;
  }
  return kps;
}
}  // namespace

const char* lmb_version(void) { return LMB_VERSION_STRING; }

lmb_status lmb_model_load(const char* path, lmb_model** out) {
  if (out == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_model_load: out is NULL");
  *out = nullptr;
  if (path == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_model_load: path is NULL");
  return guarded(LMB_ERROR_MODEL_FILE, "lmb_model_load", [&] {
    auto handle = std::make_unique<lmb_model>();
    handle->model = lmb::Model::load(path);
    *out = handle.release();
    return LMB_OK;
  });
}

lmb_status lmb_model_load_from_memory(const void* data, size_t size, lmb_model** out) {
  if (out == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_model_load_from_memory: out is NULL");
  *out = nullptr;
  if (data == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_model_load_from_memory: data is NULL");
  return guarded(LMB_ERROR_MODEL_FILE, "lmb_model_load_from_memory", [&] {
    auto handle = std::make_unique<lmb_model>();
    handle->model = lmb::Model::from_bytes(static_cast<const uint8_t*>(data), size, "model in memory");
    *out = handle.release();
    return LMB_OK;
  });
}

void lmb_model_free(lmb_model* model) { delete model; }

int lmb_model_descriptor_bytes(const lmb_model* model) { return model ? model->model->descriptor_bytes() : -1; }

int lmb_model_num_classes(const lmb_model* model) { return model ? model->model->num_classes() : -1; }

int lmb_model_is_calibrated(const lmb_model* model) {
  if (model == nullptr) return -1;
  return model->model->calibrated() ? 1 : 0;
}

void lmb_localize_options_init(lmb_localize_options* options) {
  if (options == nullptr) return;
  const lmb::LocalizerOptions d;
  options->struct_size = sizeof(lmb_localize_options);
  options->top_k = d.classifier.top_k;
  options->use_inverted_file = d.classifier.use_inverted_file ? 1 : 0;
  options->min_margin = d.classifier.min_margin;
  options->pose_top_k = d.pose_top_k;
  options->max_correspondences = d.max_correspondences;
  options->ransac_iterations = d.pose.max_iterations;
  options->max_reprojection_error_px = d.pose.max_reprojection_error_px;
  options->min_inliers = d.pose.min_inliers;
  options->seed = d.pose.seed;
  options->inverted_file_words = d.classifier.inverted_file_words;
}

lmb_status lmb_localize(const lmb_model* model, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                        const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                        const lmb_localize_options* options, lmb_pose* out_pose, lmb_match* out_matches,
                        int max_matches, int* num_matches) {
  return lmb_localize_with_confidence(model, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam,
                                      options, out_pose, nullptr, out_matches, max_matches, num_matches);
}

namespace {

// lmb_localize_with_confidence, and with a walk the frame judged in it (*continued: the walk rule
// judged it).
lmb_status localize_frame(const lmb_model* model, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                          const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                          const lmb_localize_options* options, lmb_pose* out_pose, lmb_pose_confidence* out_confidence,
                          lmb_match* out_matches, int max_matches, int* num_matches, lmb::WalkTracker* walk,
                          int* continued) {
  const char* fn = "lmb_localize";
  if (num_matches != nullptr) *num_matches = 0;
  if (out_pose != nullptr) *out_pose = lmb_pose{};
  if (out_confidence != nullptr) *out_confidence = lmb_pose_confidence{0, -1.0, -1.0, 0, 0};
  if (model == nullptr || camera == nullptr || gravity_in_cam == nullptr || out_pose == nullptr) {
    return fail(LMB_ERROR_INVALID_ARGUMENT,
                "lmb_localize: model, camera, gravity_in_cam and out_pose must not be NULL");
  }
  if (n < 0 || (n > 0 && (keypoints == nullptr || descriptors == nullptr))) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_localize: n < 0 or NULL keypoints/descriptors");
  }
  if (max_matches < 0 || (max_matches > 0 && out_matches == nullptr)) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_localize: max_matches < 0 or NULL out_matches");
  }
  if (descriptor_bytes != model->model->descriptor_bytes()) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_localize: descriptors have " + std::to_string(descriptor_bytes) +
                                                " bytes, the model expects " +
                                                std::to_string(model->model->descriptor_bytes()));
  }
  if (camera->num_params < 0 || (camera->num_params > 0 && camera->params == nullptr)) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_localize: camera params NULL or num_params < 0");
  }
  return guarded(LMB_ERROR_INVALID_ARGUMENT, fn, [&] {
    const lmb::Camera cam = to_camera(*camera);
    const lmb::LocalizerOptions lo = to_localizer_options(options);
    const std::vector<lmb::Keypoint> kps = to_keypoints(keypoints, n);
    const Eigen::Vector3d gravity(gravity_in_cam[0], gravity_in_cam[1], gravity_in_cam[2]);
    const lmb::Localizer localizer(model->model, lo);
    lmb::LocalizeResult r = localizer.localize(cam, kps, descriptors, gravity);
    if (walk != nullptr) {
      const lmb::WalkVerdict v = walk->update(r.pose.success, r.pose.cam_from_world, r.evidence);
      r.localized = v.localized;
      r.confidence = v.continues ? v.walk_confidence : v.frame_confidence;
      const auto& wc = model->model->walk_calibration();
      r.confidence_threshold = v.continues && wc ? wc->threshold : model->model->calibration().threshold;
      if (continued != nullptr) *continued = v.continues ? 1 : 0;
    }

    out_pose->success = r.localized ? 1 : 0;
    if (out_confidence != nullptr) {
      out_confidence->calibrated = r.calibrated ? 1 : 0;
      out_confidence->probability = r.confidence;
      out_confidence->threshold = r.confidence_threshold;
      out_confidence->pose_found = r.pose.success ? 1 : 0;
      out_confidence->localized = r.localized ? 1 : 0;
    }
    const Eigen::Quaterniond& q = r.pose.cam_from_world.rotation;
    out_pose->rotation[0] = q.w();
    out_pose->rotation[1] = q.x();
    out_pose->rotation[2] = q.y();
    out_pose->rotation[3] = q.z();
    for (int i = 0; i < 3; ++i) out_pose->translation[i] = r.pose.cam_from_world.translation[i];
    out_pose->num_inliers = r.pose.num_inliers;
    out_pose->num_correspondences = static_cast<int>(r.correspondence_keypoint.size());

    // Inlier flag of every match that was a correspondence.
    std::vector<char> inlier(r.matches.matches.size(), 0);
    for (size_t i = 0; i < r.correspondence_match.size(); ++i) {
      if (r.pose.inlier_mask[i]) inlier[r.correspondence_match[i]] = 1;
    }
    const int total = static_cast<int>(r.matches.matches.size());
    if (num_matches != nullptr) *num_matches = total;
    int written = 0;
    for (int32_t k = 0; k < r.matches.num_keypoints() && written < max_matches; ++k) {
      for (int32_t j = 0; j < r.matches.count(k) && written < max_matches; ++j) {
        const int32_t index = r.matches.begin[k] + j;
        const lmb::ClassMatch& m = r.matches.matches[index];
        lmb_match& out = out_matches[written++];
        out.keypoint = k;
        out.rank = j;
        out.class_id = m.cls;
        out.landmark = m.landmark;
        out.score = m.score;
        const Eigen::Vector3d& p = model->model->class_position(m.cls);
        for (int i = 0; i < 3; ++i) out.position[i] = p[i];
        out.inlier = inlier[index];
      }
    }
    if (out_matches != nullptr && total > max_matches) {
      return fail(LMB_ERROR_BUFFER_TOO_SMALL, "lmb_localize: the frame has " + std::to_string(total) +
                                                  " matches, the buffer holds " + std::to_string(max_matches));
    }
    return LMB_OK;
  });
}

}  // namespace

lmb_status lmb_localize_with_confidence(const lmb_model* model, const lmb_camera* camera, const lmb_keypoint* keypoints,
                                        int n, const uint8_t* descriptors, int descriptor_bytes,
                                        const double gravity_in_cam[3], const lmb_localize_options* options,
                                        lmb_pose* out_pose, lmb_pose_confidence* out_confidence, lmb_match* out_matches,
                                        int max_matches, int* num_matches) {
  return localize_frame(model, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam, options, out_pose,
                        out_confidence, out_matches, max_matches, num_matches, nullptr, nullptr);
}

lmb_status lmb_walk_create(const lmb_model* model, lmb_walk** out) {
  if (out == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_walk_create: out must not be NULL");
  *out = nullptr;
  if (model == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_walk_create: model must not be NULL");
  if (!model->model->calibrated()) {
    return fail(LMB_ERROR_INVALID_ARGUMENT,
                "lmb_walk_create: the model has no pose calibration (export it with `lboost export`, or run "
                "`lboost calibrate`)");
  }
  return guarded(LMB_ERROR_INVALID_ARGUMENT, "lmb_walk_create", [&] {
    *out = new lmb_walk{model->model, lmb::WalkTracker(model->model->calibration(), model->model->walk_calibration())};
    return LMB_OK;
  });
}

void lmb_walk_free(lmb_walk* walk) { delete walk; }

int lmb_walk_is_calibrated(const lmb_walk* walk) {
  if (walk == nullptr) return -1;
  return walk->model->walk_calibration().has_value() ? 1 : 0;
}

void lmb_walk_reset(lmb_walk* walk) {
  if (walk != nullptr) walk->tracker.reset();
}

lmb_status lmb_walk_localize(lmb_walk* walk, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                             const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                             const lmb_localize_options* options, lmb_pose* out_pose,
                             lmb_pose_confidence* out_confidence, int* continued) {
  if (continued != nullptr) *continued = 0;
  if (walk == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_walk_localize: walk must not be NULL");
  const lmb_model model{walk->model};
  return localize_frame(&model, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam, options, out_pose,
                        out_confidence, nullptr, 0, nullptr, &walk->tracker, continued);
}

}  // extern "C"

namespace {

// A frame's inputs in C++ form, checked as lmb_localize checks them.
struct BundleFrame {
  lmb::Camera camera;
  std::vector<lmb::Keypoint> keypoints;
  Eigen::Vector3d gravity;
};

// lmb_bundle_localize and lmb_bundle_track: checks, then `localize(frame)` under the guard.
template <class F>
lmb_status bundle_call(const char* fn, lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints,
                       int n, const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                       lmb_pose* out_pose, int* out_area, F&& localize) {
  if (out_pose != nullptr) *out_pose = lmb_pose{};
  if (out_area != nullptr) *out_area = -1;
  if (bundle == nullptr || camera == nullptr || gravity_in_cam == nullptr || out_pose == nullptr) {
    return fail(LMB_ERROR_INVALID_ARGUMENT,
                std::string(fn) + ": bundle, camera, gravity_in_cam and out_pose must not be NULL");
  }
  if (n < 0 || (n > 0 && (keypoints == nullptr || descriptors == nullptr))) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, std::string(fn) + ": n < 0 or NULL keypoints/descriptors");
  }
  if (camera->num_params < 0 || (camera->num_params > 0 && camera->params == nullptr)) {
    return fail(LMB_ERROR_INVALID_ARGUMENT, std::string(fn) + ": camera params NULL or num_params < 0");
  }
  return guarded(LMB_ERROR_INVALID_ARGUMENT, fn, [&] {
    BundleFrame frame;
    frame.camera = to_camera(*camera);
    frame.camera.check("camera");
    frame.keypoints = to_keypoints(keypoints, n);
    frame.gravity = Eigen::Vector3d(gravity_in_cam[0], gravity_in_cam[1], gravity_in_cam[2]);
    // The first area that loads tells the descriptor length (the bundle holds every area to it).
    const int32_t expected = bundle->bundle->descriptor_bytes(bundle->bundle->select(nullptr));
    if (expected >= 0 && descriptor_bytes != expected) {
      return fail(LMB_ERROR_INVALID_ARGUMENT, std::string(fn) + ": descriptors have " +
                                                  std::to_string(descriptor_bytes) +
                                                  " bytes, the bundle's models expect " + std::to_string(expected));
    }
    const lmb::BundleLocalizeResult r = localize(frame);
    if (r.scored.empty() && !r.errors.empty()) {
      std::string message = std::string(fn) + ": no selected area could be loaded: " + r.errors[0];
      if (r.errors.size() > 1) message += " (and " + std::to_string(r.errors.size() - 1) + " more)";
      return fail(LMB_ERROR_MODEL_FILE, message);
    }
    const lmb::PoseResult& pose = r.result.pose;
    // Tracking with a walk-calibrated bundle: the walk's verdict. Else a calibrated bundle's answer
    // to act on; an uncalibrated one's: a pose was found; and when tracking, a pose that passed the
    // motion gate (r.tracked is false outside track()).
    out_pose->success =
        (r.walk_judged ? r.localized : r.tracked || (r.calibrated ? r.localized : r.area >= 0 && pose.success)) ? 1 : 0;
    const Eigen::Quaterniond& q = pose.cam_from_world.rotation;
    out_pose->rotation[0] = q.w();
    out_pose->rotation[1] = q.x();
    out_pose->rotation[2] = q.y();
    out_pose->rotation[3] = q.z();
    for (int i = 0; i < 3; ++i) out_pose->translation[i] = pose.cam_from_world.translation[i];
    out_pose->num_inliers = pose.num_inliers;
    out_pose->num_correspondences = static_cast<int>(r.result.correspondence_keypoint.size());
    if (out_area != nullptr) *out_area = r.area;
    return LMB_OK;
  });
}

// The C prior as the library's (default: none given).
lmb::PositionPrior to_prior(const lmb_prior* prior) {
  lmb::PositionPrior p;
  if (prior != nullptr) {
    p.position = Eigen::Vector3d(prior->position[0], prior->position[1], prior->position[2]);
    p.radius = prior->radius;
  }
  return p;
}

// lmb_bundle_track and lmb_bundle_track_with_prior.
lmb_status track_call(const char* fn, lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints,
                      int n, const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                      double tracking_radius, const lmb_prior* prior, const lmb_localize_options* options,
                      lmb_pose* out_pose, int* out_area) {
  if (bundle != nullptr) bundle->last_tracked = 0;
  return bundle_call(fn, bundle, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam, out_pose,
                     out_area, [&](const BundleFrame& f) {
                       lmb::BundleLocalizerOptions bo;
                       bo.localizer = to_localizer_options(options);
                       bo.tracking_radius = tracking_radius;
                       bo.tracking_areas = bundle->tracking_areas;
                       bo.check();
                       // New options each call; the tracking state carries over.
                       if (bundle->tracker) {
                         bundle->tracker->set_options(bo);
                       } else {
                         bundle->tracker = std::make_unique<lmb::BundleLocalizer>(bundle->bundle, bo);
                       }
                       const lmb::PositionPrior p = to_prior(prior);
                       lmb::BundleLocalizeResult r =
                           bundle->tracker->track(f.camera, f.keypoints, descriptors, f.gravity, prior ? &p : nullptr);
                       bundle->last_tracked = r.tracked ? 1 : 0;
                       return r;
                     });
}

}  // namespace

extern "C" {

lmb_status lmb_bundle_open(const char* index_path, lmb_bundle** out) {
  if (out == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_bundle_open: out is NULL");
  *out = nullptr;
  if (index_path == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_bundle_open: index_path is NULL");
  return guarded(LMB_ERROR_MODEL_FILE, "lmb_bundle_open", [&] {
    auto handle = std::make_unique<lmb_bundle>();
    handle->bundle = lmb::AreaBundle::open(index_path);
    *out = handle.release();
    return LMB_OK;
  });
}

void lmb_bundle_free(lmb_bundle* bundle) { delete bundle; }

int lmb_bundle_num_areas(const lmb_bundle* bundle) {
  return bundle ? static_cast<int>(bundle->bundle->areas().size()) : -1;
}

int lmb_bundle_num_loaded(const lmb_bundle* bundle) {
  return bundle ? static_cast<int>(bundle->bundle->loaded_ids().size()) : -1;
}

lmb_status lmb_bundle_set_cache(lmb_bundle* bundle, int max_areas, uint64_t max_bytes) {
  if (bundle == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_bundle_set_cache: bundle is NULL");
  if (max_areas < 0) {
    return fail(LMB_ERROR_INVALID_ARGUMENT,
                "lmb_bundle_set_cache: max_areas " + std::to_string(max_areas) + " must be >= 0 (0 = no limit)");
  }
  return guarded(LMB_ERROR_INVALID_ARGUMENT, "lmb_bundle_set_cache", [&] {
    bundle->bundle->set_cache_limits(lmb::BundleCacheLimits{max_areas, max_bytes});
    return LMB_OK;
  });
}

lmb_status lmb_bundle_set_tracking_areas(lmb_bundle* bundle, int areas) {
  if (bundle == nullptr) return fail(LMB_ERROR_INVALID_ARGUMENT, "lmb_bundle_set_tracking_areas: bundle is NULL");
  if (areas < 1 || areas > 256) {
    return fail(LMB_ERROR_INVALID_ARGUMENT,
                "lmb_bundle_set_tracking_areas: areas " + std::to_string(areas) + " must be in 1..256");
  }
  bundle->tracking_areas = areas;
  return LMB_OK;
}

int lmb_bundle_tracked(const lmb_bundle* bundle) { return bundle == nullptr ? -1 : bundle->last_tracked; }

lmb_status lmb_bundle_localize(lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                               const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                               const lmb_prior* prior, const lmb_localize_options* options, lmb_pose* out_pose,
                               int* out_area) {
  return bundle_call("lmb_bundle_localize", bundle, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam,
                     out_pose, out_area, [&](const BundleFrame& f) {
                       const lmb::PositionPrior p = to_prior(prior);
                       lmb::BundleLocalizerOptions bo;
                       bo.localizer = to_localizer_options(options);
                       const lmb::BundleLocalizer localizer(bundle->bundle, bo);
                       return localizer.localize(f.camera, f.keypoints, descriptors, f.gravity,
                                                 prior != nullptr ? &p : nullptr);
                     });
}

lmb_status lmb_bundle_track(lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                            const uint8_t* descriptors, int descriptor_bytes, const double gravity_in_cam[3],
                            double tracking_radius, const lmb_localize_options* options, lmb_pose* out_pose,
                            int* out_area) {
  return track_call("lmb_bundle_track", bundle, camera, keypoints, n, descriptors, descriptor_bytes, gravity_in_cam,
                    tracking_radius, nullptr, options, out_pose, out_area);
}

lmb_status lmb_bundle_track_with_prior(lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints,
                                       int n, const uint8_t* descriptors, int descriptor_bytes,
                                       const double gravity_in_cam[3], double tracking_radius,
                                       const lmb_prior* relocalization_prior, const lmb_localize_options* options,
                                       lmb_pose* out_pose, int* out_area) {
  return track_call("lmb_bundle_track_with_prior", bundle, camera, keypoints, n, descriptors, descriptor_bytes,
                    gravity_in_cam, tracking_radius, relocalization_prior, options, out_pose, out_area);
}

}  // extern "C"
