/* infer/c_api.h must compile as ISO C90 (what it promises): this file is compiled with
   -std=c89 -pedantic-errors by the ctest infer/c_api_c89_test. */
#include "infer/c_api.h"

int lmb_c89_check(void) {
  lmb_localize_options options;
  lmb_model* model = 0;
  lmb_bundle* bundle = 0;
  lmb_prior prior;
  prior.position[0] = 0.0;
  prior.radius = 5.0;
  lmb_localize_options_init(&options);
  if (lmb_bundle_open("bundle.txt", &bundle) != LMB_OK || lmb_bundle_set_cache(bundle, 4, 0) != LMB_OK) return 2;
  if (lmb_bundle_localize(bundle, 0, 0, 0, 0, 0, 0, &prior, &options, 0, 0) != LMB_ERROR_INVALID_ARGUMENT) return 3;
  if (lmb_bundle_track_with_prior(bundle, 0, 0, 0, 0, 0, 0, 1.0, &prior, &options, 0, 0) != LMB_ERROR_INVALID_ARGUMENT)
    return 4;
  lmb_bundle_free(bundle);
  return lmb_model_load("model.lbm", &model) == LMB_OK ? 0 : 1;
}
