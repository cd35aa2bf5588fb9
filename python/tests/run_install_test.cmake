# python/install_test: installs the build into PREFIX (all components: the libraries and the
# package), then imports and uses the installed package, which must come from PREFIX and find the
# installed libraries through its RPATH.
file(REMOVE_RECURSE ${PREFIX})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX}
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
file(WRITE ${PREFIX}/check.py [=[
import sys
import numpy as np
import landmarkboost as lb
import landmarkboost.cv
import landmarkboost.io
prefix = sys.argv[1]
for mod in (lb, lb._core, lb._cv, lb._io):
    assert mod.__file__.startswith(prefix + "/"), (mod.__file__, prefix)
image = (np.random.default_rng(1).random((96, 128)) * 255).astype(np.uint8)
f = lb.cv.detect_features(image)
assert len(f.keypoints) > 0
print("installed landmarkboost", lb.__version__, "at", lb.__file__, "finds", len(f.keypoints), "keypoints")
]=])
execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${PREFIX}/${PACKAGE_DIR} PYTHONNOUSERSITE=1
                        ${PYTHON} ${PREFIX}/check.py ${PREFIX}
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the installed package does not work (${rc})")
endif()
