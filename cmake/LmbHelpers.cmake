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

# ---- SIMD kernels (common/simd/simd_level.h) -----------------------------------------------------
# The target architecture decides which kernel files are built: x86_64 (generic, avx2, avx512),
# aarch64 (generic, neon) or other (generic only). Each file is compiled with its own ISA flags;
# the code in it is also guarded by the architecture.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(LMB_SIMD_ARCH x86_64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64|ARM64)$")
  set(LMB_SIMD_ARCH aarch64)
else()
  set(LMB_SIMD_ARCH other)
endif()

# No fused multiply-adds the source does not spell out. GCC contracts a * b + c in C++ by default
# wherever the ISA has an FMA (every aarch64 CPU; x86 code built with -mfma or -march=native),
# which would make results depend on the architecture and the SIMD level, and would split a
# region bound p + s * c computed by a kernel from the same bound in a test's reference.
# Inference promises the same bits on x86 and arm64 and at every level: every target on
# architectures whose baseline has an FMA, and the inference path's own targets everywhere
# (lmb_fp_exact; the x86-64 baseline and the kernels' flags have no FMA, so the rest cannot
# contract there).
if(NOT LMB_SIMD_ARCH STREQUAL "x86_64")
  add_compile_options(-ffp-contract=off)
endif()
function(lmb_fp_exact target)
  target_compile_options(${target} PRIVATE -ffp-contract=off)
endfunction()
set(LMB_SIMD_FLAGS_avx2 -mavx2 -mpopcnt)
set(LMB_SIMD_FLAGS_avx512 -mavx512f -mavx512bw -mavx512dq -mavx512vl -mavx2 -mpopcnt)
# GCC's generic tuning splits every unaligned 256-bit load and store into two 128-bit halves. A
# kernel that copies a 32-byte vector from memory (std::memcpy into a GCC vector type) then
# stores the halves to the stack and reloads them as one 256-bit value: a store-forwarding stall
# on every load (any_lane_passes ran ~10x slower than with whole loads; docs/inference.md). The
# kernels' loads are whole vectors, as on every AVX2 CPU of the last ten years.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  foreach(isa avx2 avx512)
    list(APPEND LMB_SIMD_FLAGS_${isa} -mmove-max=256 -mstore-max=256)
  endforeach()
endif()

# lmb_simd_sources(<out var> <path prefix> ISAS <avx2|avx512|neon>... [AVX512_FLAGS <flag>...])
# Sets <out var> to <prefix>_generic.cc plus <prefix>_<isa>.cc for each ISA of this architecture,
# with the ISA's compile flags (AVX512_FLAGS: extra flags of the avx512 file).
function(lmb_simd_sources out prefix)
  cmake_parse_arguments(ARG "" "" "ISAS;AVX512_FLAGS" ${ARGN})
  set(files ${prefix}_generic.cc)
  foreach(isa ${ARG_ISAS})
    set(file ${prefix}_${isa}.cc)
    if(isa STREQUAL "neon")
      if(LMB_SIMD_ARCH STREQUAL "aarch64")
        list(APPEND files ${file})  # Advanced SIMD is part of every ARMv8-A CPU: no flags
      endif()
    elseif(LMB_SIMD_ARCH STREQUAL "x86_64")
      set(flags ${LMB_SIMD_FLAGS_${isa}})
      if(isa STREQUAL "avx512")
        list(APPEND flags ${ARG_AVX512_FLAGS})
      endif()
      set_source_files_properties(${file} PROPERTIES COMPILE_OPTIONS "${flags}")
      list(APPEND files ${file})
    endif()
  endforeach()
  set(${out} ${files} PARENT_SCOPE)
endfunction()
