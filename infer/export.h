/* Symbol export for the shared library lmb_infer. The library is compiled with hidden visibility,
   so only declarations marked LMB_INFER_EXPORT are part of its ABI; everything else (lmb::detail,
   OpenGV and lmb_common code linked into it) stays private to liblmb_infer.so. Included by the C
   API (infer/c_api.h), so it is C89: no line comments. */
#pragma once

#if defined(_WIN32)
#define LMB_INFER_EXPORT
#else
#define LMB_INFER_EXPORT __attribute__((visibility("default")))
#endif
