#!/usr/bin/env bash
# Builds PropCam's Debian package from a release build folder (prefix /usr,
# as the release preset configures it):
#   scripts/package.sh [BUILD_DIR]   -> BUILD_DIR/packages/propcam_<version>_<arch>.deb
#   scripts/package.sh --arm64       -> build/arm64/packages/propcam_<version>_arm64.deb
#                                       (cross-built: scripts/arm64.sh setup, build, package)
# The package holds the programs, the models, the virtual board, the boards
# of real hardware (/etc/propcam/boards), the systemd units, sysusers,
# tmpfiles and udev rules (board/CMakeLists.txt); its library dependencies
# come from dpkg-shlibdeps. scripts/test_package.sh installs and runs it.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ "${1:-}" == --arm64 ]]; then
  bash "$here/scripts/arm64.sh" setup >&2
  bash "$here/scripts/arm64.sh" build >&2
  bash "$here/scripts/arm64.sh" package >&2
  ls "$here"/build/arm64/packages/*.deb
  exit 0
fi
build="$(cd "${1:-$here/build/release}" && pwd)"
prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$build/CMakeCache.txt")
if [[ "$prefix" != /usr ]]; then
  echo "package.sh: $build installs under '$prefix'; a Debian package needs /usr (cmake --preset release)" >&2
  exit 1
fi
cmake --build "$build" --target propcam propcamd >&2
rm -rf "$build/packages"
(cd "$build" && cpack -G DEB -B "$build/packages" >&2)
rm -rf "$build/packages/_CPack_Packages"
ls "$build"/packages/*.deb
