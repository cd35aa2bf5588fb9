/* infer/c_api.h must compile as ISO C90 (what it promises): this file is compiled with
   -std=c89 -pedantic-errors by the ctest infer/c_api_c89_test. */
#include "infer/c_api.h"

int lmb_c89_check(void) {
  lmb_localize_options options;
  lmb_model* model = 0;
  lmb_localize_options_init(&options);
  return lmb_model_load("model.lbm", &model) == LMB_OK ? 0 : 1;
}
