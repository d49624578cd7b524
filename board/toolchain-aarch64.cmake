# Cross-compiling PropCam for arm64 (Debian bookworm, aarch64) with Debian's
# cross toolchain (crossbuild-essential-arm64): the configure preset `arm64`,
# scripts/arm64.sh, docs/arm64.md.
#
# The arm64 libraries come from a sysroot, by default build/arm64-sysroot
# (scripts/arm64.sh setup makes it with mmdebstrap; docs/arm64.md says why
# not Debian multiarch), or another one named by $PROPCAM_ARM64_SYSROOT.
# Test programs run under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR), so
# gtest_discover_tests lists them at build time and ctest runs them.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

if(DEFINED ENV{PROPCAM_ARM64_SYSROOT})
  set(_propcam_sysroot "$ENV{PROPCAM_ARM64_SYSROOT}")
elseif(EXISTS "${CMAKE_CURRENT_LIST_DIR}/../build/arm64-sysroot/usr/lib/aarch64-linux-gnu")
  get_filename_component(_propcam_sysroot "${CMAKE_CURRENT_LIST_DIR}/../build/arm64-sysroot" ABSOLUTE)
else()
  message(FATAL_ERROR "no arm64 sysroot: run scripts/arm64.sh setup, or set PROPCAM_ARM64_SYSROOT")
endif()

find_program(PROPCAM_QEMU_AARCH64 qemu-aarch64-static qemu-aarch64 NO_CMAKE_FIND_ROOT_PATH)
set(CMAKE_SYSROOT "${_propcam_sysroot}")
set(CMAKE_FIND_ROOT_PATH "${_propcam_sysroot}")
# pkg-config (libcamera, libv4l2, libgpiod, libdrm, libsystemd) reads only
# the arm64 .pc files and prefixes their paths with the sysroot.
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${_propcam_sysroot}")
set(ENV{PKG_CONFIG_LIBDIR}
  "${_propcam_sysroot}/usr/lib/aarch64-linux-gnu/pkgconfig:${_propcam_sysroot}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")
# qemu's -L: the dynamic loader and the libraries from the sysroot.
if(PROPCAM_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${PROPCAM_QEMU_AARCH64};-L;${_propcam_sysroot}")
else()
  message(WARNING "no qemu-aarch64-static: the arm64 test programs can be built but not listed or run")
endif()

# Programs (pkg-config, the emulator) from the host; libraries, headers and
# CMake packages from the target's root only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
