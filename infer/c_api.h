/* The C API of the LandmarkBoost inference library (a pure C header, usable from C89 and C++).
 *
 *   lmb_model* model = NULL;
 *   if (lmb_model_load("model.lbm", &model) != LMB_OK) fprintf(stderr, "%s\n", lmb_last_error());
 *   lmb_localize_options options;
 *   lmb_localize_options_init(&options);
 *   lmb_pose pose;
 *   lmb_localize(model, &camera, keypoints, n, descriptors, gravity, &options, &pose,
 *                matches, max_matches, &num_matches);
 *   lmb_model_free(model);
 *
 * Conventions are those of the C++ API (infer/localizer.h): keypoints in pixels of the distorted
 * image, COLMAP convention (centre of the top-left pixel at (0.5, 0.5): add 0.5 to an OpenCV
 * KeyPoint::pt), size = detector diameter in
 * pixels, angle in degrees or -1; descriptors n rows of lmb_model_descriptor_bytes() bytes;
 * gravity_in_cam the down direction in the camera frame (x right, y down, z forward); the pose is
 * cam_from_world (x_cam = R x_world + t), R as a unit quaternion (w, x, y, z).
 *
 * Errors: every function returns an lmb_status; on failure lmb_last_error() gives a message for
 * the calling thread (valid until that thread's next failing call). No C++ exception crosses this
 * API. Threading: a loaded model is immutable; lmb_localize may run concurrently on one model from
 * any number of threads.
 */
#ifndef LMB_INFER_C_API_H_
#define LMB_INFER_C_API_H_

#include <stddef.h>
#include <stdint.h>

#include "infer/export.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum lmb_status {
  LMB_OK = 0,
  LMB_ERROR_INVALID_ARGUMENT = 1, /* null pointer, bad size, invalid camera or option */
  LMB_ERROR_MODEL_FILE = 2,       /* model file missing, unreadable, wrong format or corrupt */
  LMB_ERROR_BUFFER_TOO_SMALL = 3, /* the matches buffer is too small (the count is still set) */
  LMB_ERROR_OUT_OF_MEMORY = 4,
  LMB_ERROR_INTERNAL = 5
} lmb_status;

/* Opaque handle of a loaded model. */
typedef struct lmb_model lmb_model;

/* Camera models, COLMAP's ids and parameter orders (common/camera.h). */
typedef enum lmb_camera_model {
  LMB_CAMERA_SIMPLE_PINHOLE = 0, /* f, cx, cy */
  LMB_CAMERA_PINHOLE = 1,        /* fx, fy, cx, cy */
  LMB_CAMERA_SIMPLE_RADIAL = 2,  /* f, cx, cy, k */
  LMB_CAMERA_RADIAL = 3,         /* f, cx, cy, k1, k2 */
  LMB_CAMERA_OPENCV = 4,         /* fx, fy, cx, cy, k1, k2, p1, p2 */
  LMB_CAMERA_FULL_OPENCV = 6     /* fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 */
} lmb_camera_model;

typedef struct lmb_camera {
  int model; /* lmb_camera_model */
  int width;
  int height;
  const double* params;
  int num_params;
} lmb_camera;

typedef struct lmb_keypoint {
  float x;
  float y;
  float size;  /* detector diameter, pixels */
  float angle; /* degrees, or -1 */
} lmb_keypoint;

/* Options of lmb_localize. struct_size is the size of the struct the caller was compiled with
 * (lmb_localize_options_init sets it to sizeof(lmb_localize_options)): new options are only ever
 * appended, so a caller built against an older header passes a smaller size and gets the
 * defaults of the fields it does not know; a size below the first version's is an error. */
typedef struct lmb_localize_options {
  size_t struct_size;               /* sizeof(lmb_localize_options), set by lmb_localize_options_init */
  int top_k;                        /* matches kept per keypoint (default 1) */
  int use_inverted_file;            /* 0: score all classes; 1: the word's candidates (default 0) */
  double min_margin;                /* score above the background's (default 0) */
  int pose_top_k;                   /* matches per keypoint fed to the pose (default 1) */
  int max_correspondences;          /* best-margin matches fed to the pose, 0 = all (default 0) */
  int ransac_iterations;            /* default 500 */
  double max_reprojection_error_px; /* inlier threshold, default 8 */
  int min_inliers;                  /* default 12 */
  uint64_t seed;                    /* RANSAC seed, default 0 */
  /* Appended in 0.1; a caller's shorter struct gets the default. */
  int inverted_file_words; /* with use_inverted_file: the candidates of the keypoint's N nearest
                              words, 1..256 (default 1: its own word; 2: multiple assignment) */
} lmb_localize_options;

typedef struct lmb_pose {
  int success;           /* 1 when the frame is localized: a pose was found (at least min_inliers
                            inliers) and, when the model is calibrated, its confidence reaches the
                            model's operating point (lmb_pose_confidence) */
  double rotation[4];    /* cam_from_world rotation, unit quaternion w, x, y, z */
  double translation[3]; /* cam_from_world translation, map units */
  int num_inliers;
  int num_correspondences; /* matches given to RANSAC */
} lmb_pose;

/* The confidence of a pose (lmb_localize_with_confidence; infer/pose_confidence.h). */
typedef struct lmb_pose_confidence {
  int calibrated;     /* 1 when the model holds a pose calibration (lmb_model_is_calibrated) */
  double probability; /* P(the pose is within 20 cm / 5 deg of the truth), in [0, 1) when
                         calibrated (0 without a pose); -1 when not calibrated */
  double threshold;   /* the model's operating point when calibrated; -1 otherwise */
  int pose_found;     /* 1 when RANSAC found a pose of at least min_inliers inliers */
  int localized;      /* the same as lmb_pose.success */
} lmb_pose_confidence;

typedef struct lmb_match {
  int32_t keypoint; /* index into the input keypoints */
  int32_t rank;     /* 0 = the keypoint's best match */
  int32_t class_id; /* landmark class */
  int64_t landmark; /* map landmark id */
  double score;
  double position[3]; /* landmark position, world frame */
  int inlier;         /* 1 when this match is an inlier of the pose */
} lmb_match;

/* The message of the calling thread's last failure ("" when none). Never NULL. */
LMB_INFER_EXPORT const char* lmb_last_error(void);
/* The library version, "MAJOR.MINOR.PATCH". */
LMB_INFER_EXPORT const char* lmb_version(void);

/* Loads model.lbm into *out (set to NULL on failure). */
LMB_INFER_EXPORT lmb_status lmb_model_load(const char* path, lmb_model** out);
/* The same from a file image in memory (the bytes are copied). */
LMB_INFER_EXPORT lmb_status lmb_model_load_from_memory(const void* data, size_t size, lmb_model** out);
/* Frees a model (NULL is allowed). */
LMB_INFER_EXPORT void lmb_model_free(lmb_model* model);
/* Model facts; -1 for a NULL model. */
LMB_INFER_EXPORT int lmb_model_descriptor_bytes(const lmb_model* model);
LMB_INFER_EXPORT int lmb_model_num_classes(const lmb_model* model);
/* 1 when the model holds a pose calibration (written by `lboost export`, model format 3), 0 when
 * not (older models: a pose is trusted by its inlier count alone), -1 for a NULL model. */
LMB_INFER_EXPORT int lmb_model_is_calibrated(const lmb_model* model);

/* Defaults of every option, and struct_size. */
LMB_INFER_EXPORT void lmb_localize_options_init(lmb_localize_options* options);

/* Localizes one frame of n keypoints. options may be NULL (defaults). out_matches may be NULL
 * when max_matches is 0; *num_matches (may be NULL) receives the number of matches of the frame
 * (ranked matches of every keypoint, keypoint after keypoint, best first); when out_matches is
 * not NULL and that number exceeds max_matches, the first max_matches are written, the pose is
 * still computed, and the call returns LMB_ERROR_BUFFER_TOO_SMALL. */
LMB_INFER_EXPORT lmb_status lmb_localize(const lmb_model* model, const lmb_camera* camera,
                                         const lmb_keypoint* keypoints, int n, const uint8_t* descriptors,
                                         int descriptor_bytes, const double gravity_in_cam[3],
                                         const lmb_localize_options* options, lmb_pose* out_pose,
                                         lmb_match* out_matches, int max_matches, int* num_matches);
/* lmb_localize, and the pose's confidence into *out_confidence (may be NULL). */
LMB_INFER_EXPORT lmb_status lmb_localize_with_confidence(
    const lmb_model* model, const lmb_camera* camera, const lmb_keypoint* keypoints, int n, const uint8_t* descriptors,
    int descriptor_bytes, const double gravity_in_cam[3], const lmb_localize_options* options, lmb_pose* out_pose,
    lmb_pose_confidence* out_confidence, lmb_match* out_matches, int max_matches, int* num_matches);

/* Walks: a camera localized frame after frame (infer/walk_confidence.h). A walk keeps the last
 * trusted pose; a frame's pose is reported (lmb_pose.success) when the model's pose calibration
 * reports it, or when it continues the walk by the model's walk calibration (model format 4 or 5),
 * and, when that calibration has an agreement (format 5), the pose agrees with the pose of the frame
 * before (docs/walks.md). With a model without a walk calibration every frame is judged as
 * lmb_localize_with_confidence judges it.
 *
 *   lmb_walk* walk = NULL;
 *   lmb_walk_create(model, &walk);
 *   for each frame: lmb_walk_localize(walk, &camera, keypoints, n, descriptors, 64, gravity, NULL,
 *                                     &pose, &confidence);
 *   lmb_walk_free(walk);
 *
 * Threading: one walk follows one camera from one thread at a time; walks of one model may run on
 * different threads at once. */
typedef struct lmb_walk lmb_walk;
/* A walk on a calibrated model (lmb_model_is_calibrated); the model is shared, not copied, and
 * must outlive nothing: the walk keeps its own reference. *out is NULL on failure. */
LMB_INFER_EXPORT lmb_status lmb_walk_create(const lmb_model* model, lmb_walk** out);
/* Frees a walk (NULL is allowed). */
LMB_INFER_EXPORT void lmb_walk_free(lmb_walk* walk);
/* 1 when the walk's model holds a walk calibration, 0 when not, -1 for a NULL walk. */
LMB_INFER_EXPORT int lmb_walk_is_calibrated(const lmb_walk* walk);
/* Forgets the last trusted and estimated poses (the next frame is judged on its own). */
LMB_INFER_EXPORT void lmb_walk_reset(lmb_walk* walk);
/* Localizes the walk's next frame as lmb_localize_with_confidence does (no matches written) and
 * judges it in the walk: out_pose->success and out_confidence->localized are the walk's verdict;
 * out_confidence->probability is the walk rule's probability when the walk continued (a trusted
 * pose at most a few frames back) and the pose calibration's otherwise; *continued (may be NULL)
 * is 1 when the walk rule judged the frame. */
LMB_INFER_EXPORT lmb_status lmb_walk_localize(lmb_walk* walk, const lmb_camera* camera, const lmb_keypoint* keypoints,
                                              int n, const uint8_t* descriptors, int descriptor_bytes,
                                              const double gravity_in_cam[3], const lmb_localize_options* options,
                                              lmb_pose* out_pose, lmb_pose_confidence* out_confidence, int* continued);

/* Bundles of area models (docs/areas.md): a map split into areas, one model each, with an index
 * (bundle.txt). Opening reads the index only; an area's model is read on first use and freed again
 * under the cache limits (least recently used first).
 *
 *   lmb_bundle* bundle = NULL;
 *   lmb_bundle_open("bundle/bundle.txt", &bundle);
 *   lmb_prior prior;  prior.position = {x, y, z};  prior.radius = 10.0;
 *   lmb_bundle_localize(bundle, &camera, keypoints, n, descriptors, 32, gravity, &prior, NULL,
 *                       &pose, &area);
 *   lmb_bundle_free(bundle);
 *
 * Threading: lmb_bundle_localize may run concurrently on one bundle; lmb_bundle_track keeps the
 * last pose in the bundle handle, so it tracks one camera from one thread at a time. */
typedef struct lmb_bundle lmb_bundle;

/* The camera centre is within radius metres (>= 0) of position (world frame). */
typedef struct lmb_prior {
  double position[3];
  double radius;
} lmb_prior;

/* Opens bundle.txt into *out (set to NULL on failure; LMB_ERROR_MODEL_FILE names the line). */
LMB_INFER_EXPORT lmb_status lmb_bundle_open(const char* index_path, lmb_bundle** out);
/* Frees a bundle and its loaded areas (NULL is allowed). */
LMB_INFER_EXPORT void lmb_bundle_free(lmb_bundle* bundle);
/* Bundle facts; -1 for a NULL bundle. */
LMB_INFER_EXPORT int lmb_bundle_num_areas(const lmb_bundle* bundle);
LMB_INFER_EXPORT int lmb_bundle_num_loaded(const lmb_bundle* bundle);
/* At most max_areas areas and max_bytes model bytes loaded (0 = no limit); applied at once. */
LMB_INFER_EXPORT lmb_status lmb_bundle_set_cache(lmb_bundle* bundle, int max_areas, uint64_t max_bytes);

/* Localizes one frame in the areas the prior selects, nearest first: the first area whose model is
 * calibrated and whose pose reaches its operating point wins and the rest are not scored; when
 * none does, and without a prior (every area), the pose that explains most of the frame's keypoints
 * with the matches of every scored area wins (lmb::AreaSearch::kNearestFirst,
 * lmb::AreaWinner::kSupport). out_pose->success: with a calibrated bundle (lboost bundle --map) the
 * bundle's confidence reaches its operating point, else a pose was found. Arguments as
 * lmb_localize; *out_area (may be NULL) receives the winning area
 * (-1 without a pose). Areas that cannot be loaded are skipped; when every selected area fails,
 * the call returns LMB_ERROR_MODEL_FILE naming them. */
LMB_INFER_EXPORT lmb_status lmb_bundle_localize(lmb_bundle* bundle, const lmb_camera* camera,
                                                const lmb_keypoint* keypoints, int n, const uint8_t* descriptors,
                                                int descriptor_bytes, const double gravity_in_cam[3],
                                                const lmb_prior* prior, const lmb_localize_options* options,
                                                lmb_pose* out_pose, int* out_area);
/* Tracking (BundleLocalizer::track, docs/areas.md): the areas near the last tracked pose, those that
 * see most of its view first, until the winning pose lies within tracking_radius metres of it (a
 * camera's motion between two frames); the first frame, and a frame those areas do not localize,
 * are localized in every area. out_pose->success: with a bundle that has a walk calibration
 * (lboost bundle --map), the walk's verdict (the frame's confidence or the walk's continuation,
 * and agreement with the walk's pose before: docs/walks.md); else as lmb_bundle_localize, or the
 * pose passed that motion gate (tracked). */
LMB_INFER_EXPORT lmb_status lmb_bundle_track(lmb_bundle* bundle, const lmb_camera* camera,
                                             const lmb_keypoint* keypoints, int n, const uint8_t* descriptors,
                                             int descriptor_bytes, const double gravity_in_cam[3],
                                             double tracking_radius, const lmb_localize_options* options,
                                             lmb_pose* out_pose, int* out_area);
/* lmb_bundle_track with a relocalization prior (e.g. a GPS fix; NULL: as lmb_bundle_track): the
 * first frame, and a frame the tracked areas do not localize, are localized in the areas the prior
 * selects, nearest first (as lmb_bundle_localize with that prior), instead of in every area. */
LMB_INFER_EXPORT lmb_status lmb_bundle_track_with_prior(
    lmb_bundle* bundle, const lmb_camera* camera, const lmb_keypoint* keypoints, int n, const uint8_t* descriptors,
    int descriptor_bytes, const double gravity_in_cam[3], double tracking_radius, const lmb_prior* relocalization_prior,
    const lmb_localize_options* options, lmb_pose* out_pose, int* out_area);
/* Areas lmb_bundle_track scores before its motion gate judges the winning pose (1..256; default
 * 2: a second area's matches confirm the pose; 1 is about twice as fast). */
LMB_INFER_EXPORT lmb_status lmb_bundle_set_tracking_areas(lmb_bundle* bundle, int areas);
/* 1 when the last lmb_bundle_track call's pose passed the motion gate (tracked), 0 otherwise
 * (also before any call, and after a call that failed); -1 for a NULL bundle. */
LMB_INFER_EXPORT int lmb_bundle_tracked(const lmb_bundle* bundle);

#ifdef __cplusplus
}
#endif

#endif /* LMB_INFER_C_API_H_ */
