# Shared build helpers: warnings, test registration.

function(lmb_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-unused-parameter
                         $<$<CXX_COMPILER_ID:GNU>:-Wshadow=local>)  # clang (fuzz build) lacks it
  if(LMB_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# lmb_add_test(<folder>/<name> SOURCES ... [LIBS ...] [LABELS ...] [TIMEOUT s])
# Builds one GoogleTest binary and registers it as ctest test "<folder>/<name>".
function(lmb_add_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  string(REPLACE "/" "_" target ${name})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gtest_main)
  lmb_set_warnings(${target})
  add_test(NAME ${name} COMMAND ${target})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  set_tests_properties(${name} PROPERTIES TIMEOUT ${ARG_TIMEOUT}
                       ENVIRONMENT "LMB_SHARED_DATA=${LMB_SHARED_DATA};LMB_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
  if(ARG_LABELS)
    set_tests_properties(${name} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

# The environment OpenMPI 4.1 needs to run oversubscribed as root inside a container.
set(LMB_MPI_TEST_ENV
    "OMPI_ALLOW_RUN_AS_ROOT=1"
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
    "OMPI_MCA_rmaps_base_oversubscribe=1"
    "OMPI_MCA_btl_vader_single_copy_mechanism=none")
# For the sanitizer builds (scripts/sanitize.sh): OpenMPI is built without frame pointers, so
# LeakSanitizer's fast unwinder stops inside it and OpenMPI's own leaks at exit cannot be told from
# ours. The MPI tests take full (slower) stacks, which test/sanitizers/lsan.supp matches against
# OpenMPI's libraries; leak detection stays on for our code. No effect without ASan.
set(LMB_MPI_TEST_ENV_MODIFICATION "LSAN_OPTIONS=string_append::fast_unwind_on_malloc=0")

# lmb_add_mpi_test(<name> TARGET <exe> NP 2 3 [ARGS ...])
# Registers "<name>/np<N>" for each N, run through mpiexec with real ranks.
function(lmb_add_mpi_test name)
  cmake_parse_arguments(ARG "" "TARGET;TIMEOUT" "NP;ARGS" ${ARGN})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  foreach(np ${ARG_NP})
    add_test(NAME ${name}/np${np}
             COMMAND ${MPIEXEC_EXECUTABLE} ${MPIEXEC_NUMPROC_FLAG} ${np} ${MPIEXEC_PREFLAGS}
                     $<TARGET_FILE:${ARG_TARGET}> ${MPIEXEC_POSTFLAGS} ${ARG_ARGS})
    set_tests_properties(${name}/np${np} PROPERTIES TIMEOUT ${ARG_TIMEOUT} PROCESSORS ${np}
                         ENVIRONMENT "${LMB_MPI_TEST_ENV}"
                         ENVIRONMENT_MODIFICATION "${LMB_MPI_TEST_ENV_MODIFICATION}")
  endforeach()
endfunction()
