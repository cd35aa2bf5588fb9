# Driver of the ctest e2e/consumer_test (cmake -P). Installs the inference component of a build
# tree into a fresh prefix and checks that exactly the public headers are installed, that they
# include only each other and that the library exports only names they declare; then builds and runs the consumer project against it twice: through
# find_package(LandmarkBoost CONFIG) (which also compiles every installed header alone,
# header_check in CMakeLists.txt) and through pkg-config; then the optional OpenCV front-end
# (component infer_cv) through find_package(... COMPONENTS infer_cv) and pkg-config.
# Inputs: LMB_BUILD_DIR, CONSUMER_SOURCE_DIR, WORK_DIR, GENERATOR, CXX_COMPILER; optional
# CONSUMER_C_FLAGS, CONSUMER_CXX_FLAGS, CONSUMER_LINK_FLAGS: the build's own flags (e.g. the
# sanitizers' -fsanitize=..., without which a consumer cannot link a sanitized library).
cmake_minimum_required(VERSION 3.22)
foreach(var LMB_BUILD_DIR CONSUMER_SOURCE_DIR WORK_DIR GENERATOR CXX_COMPILER)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_consumer_test.cmake: -D${var}=... is required")
  endif()
endforeach()

function(run what)
  message(STATUS "consumer test: ${what}")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer test: '${what}' failed (${rc}): ${ARGN}")
  endif()
endfunction()

separate_arguments(c_flags UNIX_COMMAND "${CONSUMER_C_FLAGS}")
separate_arguments(cxx_flags UNIX_COMMAND "${CONSUMER_CXX_FLAGS}")
separate_arguments(link_flags UNIX_COMMAND "${CONSUMER_LINK_FLAGS}")

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
run("install" ${CMAKE_COMMAND} --install ${LMB_BUILD_DIR} --prefix ${prefix} --component infer)

# The public headers, and only they, are installed (the list of infer/CMakeLists.txt and
# common/CMakeLists.txt, kept here on purpose: a header becomes public by a change to both), and
# the installed headers are closed: every "..." include names an installed header. Checked for the
# component infer alone, then with infer_cv.
set(infer_headers
    common/camera.h common/context_regions.h common/error.h common/random.h common/rigid3.h
    common/shared_stump.h common/types.h common/vocabulary.h
    infer/area_bundle.h infer/bundle_index.h infer/bundle_localizer.h infer/c_api.h infer/classifier_options.h infer/export.h infer/localizer.h
    infer/model.h infer/pose_confidence.h infer/pose_estimator.h infer/ransac.h infer/version.h infer/walk_confidence.h)
set(infer_cv_headers common/detector_options.h infer/cv/feature_detection.h)
set(include_dir ${prefix}/include/landmarkboost)

function(check_installed_headers component)
  set(expected ${ARGN})
  list(SORT expected)
  file(GLOB_RECURSE installed LIST_DIRECTORIES false RELATIVE ${prefix}/include ${prefix}/include/*)
  set(got)
  foreach(file ${installed})
    if(NOT file MATCHES "^landmarkboost/")
      message(FATAL_ERROR "consumer test: ${component}: ${prefix}/include/${file} is outside include/landmarkboost")
    endif()
    string(REGEX REPLACE "^landmarkboost/" "" file ${file})
    list(APPEND got ${file})
  endforeach()
  list(SORT got)
  set(extra ${got})
  list(REMOVE_ITEM extra ${expected})
  set(missing ${expected})
  if(got)
    list(REMOVE_ITEM missing ${got})
  endif()
  if(extra)
    message(FATAL_ERROR "consumer test: ${component}: installed headers that are not public: ${extra}")
  endif()
  if(missing)
    message(FATAL_ERROR "consumer test: ${component}: public headers that are not installed: ${missing}")
  endif()
  foreach(file ${got})
    file(STRINGS ${include_dir}/${file} lines REGEX "^[ \t]*#[ \t]*include")
    foreach(line ${lines})
      # No installed header may pull in MPI, HDF5 or OpenCV (only the front-end's infer/cv/ may
      # name OpenCV) ...
      if(line MATCHES "#[ \t]*include[ \t]*[<\"](mpi|H5|hdf5)" OR
         (line MATCHES "#[ \t]*include[ \t]*[<\"]opencv" AND NOT file MATCHES "^infer/cv/"))
        message(FATAL_ERROR "consumer test: installed header ${file} includes MPI, HDF5 or OpenCV: ${line}")
      endif()
      # ... nor a LandmarkBoost header that is not installed (the project's includes are "...").
      if(line MATCHES "#[ \t]*include[ \t]*\"([^\"]+)\"")
        if(NOT EXISTS ${include_dir}/${CMAKE_MATCH_1})
          message(FATAL_ERROR "consumer test: installed header ${file} includes ${CMAKE_MATCH_1}, which is not installed")
        endif()
      endif()
    endforeach()
  endforeach()
  list(LENGTH got count)
  message(STATUS "consumer test: ${component}: the ${count} installed headers are the public ones and include only each other")
endfunction()

check_installed_headers(infer ${infer_headers})

# The shared library exports only what the installed headers declare: every lmb:: name (function or
# class) and every C function among its dynamic symbols appears in them.
file(GLOB_RECURSE infer_libs ${prefix}/*/liblmb_infer.so)
list(LENGTH infer_libs count)
if(NOT count EQUAL 1)
  message(FATAL_ERROR "consumer test: expected one installed liblmb_infer.so, found '${infer_libs}'")
endif()
find_program(NM nm REQUIRED)
execute_process(COMMAND ${NM} -D -C --defined-only ${infer_libs} OUTPUT_VARIABLE symbols RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "consumer test: nm -D -C failed on ${infer_libs}")
endif()
set(header_text "")
foreach(file ${infer_headers})
  file(READ ${include_dir}/${file} text)
  string(APPEND header_text " ${text} ")
endforeach()
# "<address> <type> <name>": each name's first lmb:: component (after "typeinfo for " and the
# like), and the C functions lmb_*. (Matched in the text: demangled names hold brackets, which
# CMake lists do not split well.)
string(REGEX MATCHALL "[ \t][A-Za-z] ([a-zA-Z ]+ for )?lmb(::|_)[A-Za-z_0-9]+" matches "${symbols}")
set(exported_names)
foreach(match ${matches})
  string(REGEX REPLACE "^.*lmb::" "" name "${match}")
  string(REGEX REPLACE "^.* (lmb_)" "\\1" name "${name}")
  list(APPEND exported_names ${name})
endforeach()
list(REMOVE_DUPLICATES exported_names)
list(LENGTH exported_names count)
if(count LESS 10)
  message(FATAL_ERROR "consumer test: only ${count} LandmarkBoost names among the exported symbols: '${exported_names}'")
endif()
foreach(name ${exported_names})
  if(NOT header_text MATCHES "[^A-Za-z_0-9]${name}[^A-Za-z_0-9]")
    message(FATAL_ERROR "consumer test: liblmb_infer.so exports lmb::${name} (or ${name}), "
                        "which no installed header declares")
  endif()
endforeach()
message(STATUS "consumer test: the ${count} names liblmb_infer.so exports are all in the installed headers")

# The optional OpenCV front-end (component infer_cv) into the same prefix: its header and
# pkg-config file are the only installed files that may name OpenCV.
run("install infer_cv" ${CMAKE_COMMAND} --install ${LMB_BUILD_DIR} --prefix ${prefix} --component infer_cv)
check_installed_headers("infer + infer_cv" ${infer_headers} ${infer_cv_headers})

# 1. CMake package.
run("configure the consumer" ${CMAKE_COMMAND} -S ${CONSUMER_SOURCE_DIR} -B ${WORK_DIR}/build
    -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX_COMPILER}
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
    "-DCMAKE_C_FLAGS=${CONSUMER_C_FLAGS}" "-DCMAKE_CXX_FLAGS=${CONSUMER_CXX_FLAGS}"
    "-DCMAKE_EXE_LINKER_FLAGS=${CONSUMER_LINK_FLAGS}")
run("build the consumer" ${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run("run the consumer" ${WORK_DIR}/build/lmb_consumer)
if(NOT EXISTS ${WORK_DIR}/build/lmb_consumer_cv)
  message(FATAL_ERROR "consumer test: find_package found no LandmarkBoost::infer_cv after installing it")
endif()
run("run the OpenCV front-end consumer" ${WORK_DIR}/build/lmb_consumer_cv)

# 2. pkg-config, from wherever the libdir is (lib or lib/<multiarch>).
file(GLOB_RECURSE pc_files ${prefix}/*/landmarkboost-infer.pc)
list(LENGTH pc_files count)
if(NOT count EQUAL 1)
  message(FATAL_ERROR "consumer test: expected one installed landmarkboost-infer.pc, found '${pc_files}'")
endif()
get_filename_component(pc_dir ${pc_files} DIRECTORY)
get_filename_component(lib_dir ${pc_dir} DIRECTORY)
execute_process(COMMAND ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${pc_dir}
                        pkg-config --cflags --libs landmarkboost-infer
                OUTPUT_VARIABLE flags OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "consumer test: pkg-config --cflags --libs landmarkboost-infer failed")
endif()
message(STATUS "consumer test: pkg-config flags: ${flags}")
if(NOT flags MATCHES "include/landmarkboost")
  message(FATAL_ERROR "consumer test: pkg-config gives no include/landmarkboost directory")
endif()
separate_arguments(flags UNIX_COMMAND "${flags}")
# The C part (c_check.c) is compiled as C99 with the same flags.
find_program(C_COMPILER NAMES cc gcc REQUIRED)
run("compile the C part with pkg-config flags"
    ${C_COMPILER} -std=c99 -Wall -Wextra -Werror -O2 -c ${CONSUMER_SOURCE_DIR}/c_check.c ${flags} ${c_flags}
    -o ${WORK_DIR}/c_check.o)
run("build the consumer with pkg-config flags"
    ${CXX_COMPILER} -std=c++17 -O2 ${CONSUMER_SOURCE_DIR}/main.cc ${WORK_DIR}/c_check.o ${flags} ${cxx_flags} ${link_flags}
    -Wl,-rpath,${lib_dir} -o ${WORK_DIR}/lmb_consumer_pkgconfig)
run("run the pkg-config consumer" ${WORK_DIR}/lmb_consumer_pkgconfig)
# 3. The OpenCV front-end through pkg-config (landmarkboost-infer-cv requires opencv4).
execute_process(COMMAND ${CMAKE_COMMAND} -E env PKG_CONFIG_PATH=${pc_dir}
                        pkg-config --cflags --libs landmarkboost-infer-cv
                OUTPUT_VARIABLE cv_flags OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "consumer test: pkg-config --cflags --libs landmarkboost-infer-cv failed")
endif()
separate_arguments(cv_flags UNIX_COMMAND "${cv_flags}")
run("build the OpenCV front-end consumer with pkg-config flags"
    ${CXX_COMPILER} -std=c++17 -O2 ${CONSUMER_SOURCE_DIR}/cv_main.cc ${cv_flags} ${cxx_flags} ${link_flags}
    -Wl,-rpath,${lib_dir} -o ${WORK_DIR}/lmb_consumer_cv_pkgconfig)
run("run the pkg-config OpenCV front-end consumer" ${WORK_DIR}/lmb_consumer_cv_pkgconfig)
message(STATUS "consumer test: passed")
