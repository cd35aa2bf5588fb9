# Cross build for 64-bit ARM Linux with Debian's cross toolchain (crossbuild-essential-arm64) and
# the arm64 packages of the dependencies installed through multiarch (/usr/lib/aarch64-linux-gnu;
# scripts/install_cross_deps.sh). Test executables run under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR),
# so `ctest` in the build folder runs them as if natively. Used by scripts/cross_test.sh.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# Headers-only packages (Eigen, cereal) and CMake package files live in the host's /usr; arm64
# libraries in /usr/lib/aarch64-linux-gnu, which CMAKE_LIBRARY_ARCHITECTURE selects.
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu /usr)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
# -L: qemu looks for the target's loader and libraries under this root first, then in the host's
# multiarch folders.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L /usr/aarch64-linux-gnu)
# ldd for the target's libraries (the link hygiene test): the target's dynamic loader under qemu.
set(LMB_CROSS_LDD "qemu-aarch64 -L /usr/aarch64-linux-gnu /usr/aarch64-linux-gnu/lib/ld-linux-aarch64.so.1 --list")
