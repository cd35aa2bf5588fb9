/* The C API from a C translation unit: proves infer/c_api.h is plain C (compiled as C99). */
#include <stdio.h>

#include "infer/c_api.h"

int lmb_consumer_c_localize(const char* model_path, const lmb_camera* camera, const lmb_keypoint* keypoints, int n,
                            const uint8_t* descriptors, const double gravity[3], lmb_pose* pose) {
  lmb_model* model = NULL;
  lmb_localize_options options;
  lmb_match matches[512];
  int num_matches = 0;
  lmb_status status = lmb_model_load(model_path, &model);
  if (status != LMB_OK) {
    printf("      C: lmb_model_load failed: %s\n", lmb_last_error());
    return 1;
  }
  lmb_localize_options_init(&options);
  status = lmb_localize(model, camera, keypoints, n, descriptors, lmb_model_descriptor_bytes(model), gravity, &options,
                        pose, matches, 512, &num_matches);
  if (status != LMB_OK) {
    printf("      C: lmb_localize failed (%d): %s\n", (int)status, lmb_last_error());
    lmb_model_free(model);
    return 1;
  }
  printf("      C: %d matches, pose success %d with %d inliers (library %s)\n", num_matches, pose->success,
         pose->num_inliers, lmb_version());
  /* A bad path gives a status and a message, never a crash or an exception. */
  lmb_model_free(model);
  model = NULL;
  if (lmb_model_load("/nonexistent.lbm", &model) != LMB_ERROR_MODEL_FILE || lmb_last_error()[0] == '\0') return 1;
  return 0;
}
