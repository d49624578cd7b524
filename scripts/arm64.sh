#!/usr/bin/env bash
# PropCam for arm64 by cross-compilation (docs/arm64.md). Opt-in: none of
# this is part of scripts/setup.sh or CI.
#
#   scripts/arm64.sh setup     host tools (cross gcc, qemu-user) and an arm64 sysroot
#   scripts/arm64.sh build     configure (preset arm64) and build propcam propcamd module_tests
#   scripts/arm64.sh package   build/arm64/packages/propcam_<version>_arm64.deb
#   scripts/arm64.sh test      the module test programs and the CLI under qemu-user
#   scripts/arm64.sh all       the four in turn
#
# The host keeps its amd64 packages: the arm64 libraries are not installed
# on the host (Debian's libopencv-dev, libceres-dev, libopenimageio-dev and
# others are not Multi-Arch: same, so apt would remove their amd64 halves)
# but extracted into a sysroot, build/arm64-sysroot, by mmdebstrap. The host
# gets only crossbuild-essential-arm64, qemu-user-static and mmdebstrap,
# after `apt-get install -s` shows that nothing would be removed or
# downgraded.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$here/build/arm64"
sysroot="${PROPCAM_ARM64_SYSROOT:-$here/build/arm64-sysroot}"
multiarch=aarch64-linux-gnu
qemu=/usr/bin/qemu-aarch64-static
nice=(nice -n "${PROPCAM_NICE:-10}")

host_packages=(crossbuild-essential-arm64 qemu-user-static mmdebstrap)
# What the project links (scripts/setup.sh's libraries), as arm64 packages,
# and the C/C++ runtime the cross compiler needs inside a sysroot.
sysroot_packages=(
  libc6-dev libstdc++-12-dev libgcc-12-dev
  libcamera-dev libv4l-dev libgpiod-dev libdrm-dev libsystemd-dev libjpeg62-turbo-dev
  libopencv-dev libopencv-contrib-dev libeigen3-dev libembree-dev libceres-dev libopenimageio-dev
  libcli11-dev nlohmann-json3-dev libspdlog-dev libtinyobjloader-dev libfreetype-dev
  libgtest-dev libgmock-dev
  # OpenImageIO's CMake package names its tools (iconvert, ...) as imported
  # targets and fails where they are missing.
  openimageio-tools
)

say() { echo "arm64.sh: $*" >&2; }
elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }

# ---------------------------------------------------------------- setup
install_host_packages() {
  local missing=() p
  for p in "${host_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]} == 0)); then
    say "host packages present: ${host_packages[*]}"
    return
  fi
  local SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q >&2
  # Dry run first: the host's packages must stay as they are.
  local sim
  sim=$(apt-get install -s -q --no-install-recommends "${missing[@]}")
  local removed downgraded
  removed=$(grep '^Remv ' <<<"$sim" || true)
  downgraded=$(grep -E '^Inst [^ ]+ \[([^]]+)\] \(([^ ]+)' <<<"$sim" |
    while read -r _ pkg old new _; do
      old=${old#[}; old=${old%]}; new=${new#(}
      if dpkg --compare-versions "$new" lt "$old"; then echo "Downgrade $pkg $old -> $new"; fi
    done || true)
  if [ -n "$removed$downgraded" ]; then
    say "apt would remove or downgrade host packages; not installing:"
    printf '%s\n' "$removed" "$downgraded" | sed '/^$/d' >&2
    exit 1
  fi
  local upgraded
  upgraded=$(grep -E '^Inst [^ ]+ \[' <<<"$sim" | awk '{print $2, $3, "->", $4}' | tr -d '[]()' || true)
  say "installing on the host: ${missing[*]}"
  say "with their dependencies: $(grep -c '^Inst ' <<<"$sim") packages; removed: none; downgraded: none"
  if [ -n "$upgraded" ]; then say "upgraded (newer Debian point release):"; echo "$upgraded" >&2; fi
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
}

# Absolute symlinks in the sysroot (ld.so, library links) point at the host's
# files: make them relative so they stay inside it, for the linker and for
# qemu's -L.
relativize_links() {
  local link target
  while IFS= read -r -d '' link; do
    target=$(readlink "$link")
    [[ "$target" == /* ]] || continue
    ln -snf "$(realpath -m --relative-to="$(dirname "$link")" "$sysroot$target")" "$link"
  done < <(find "$sysroot" -type l -lname '/*' -print0)
}

# Links that maintainer scripts would make with update-alternatives (BLAS
# and LAPACK's libblas.so.3, liblapack.so.3): mmdebstrap's extract variant
# runs no maintainer script, so they are made here, the highest priority
# winning, as update-alternatives would choose.
make_alternatives() {
  local deb link name path
  for deb in "$sysroot"/var/cache/apt/archives/*.deb; do
    dpkg-deb --ctrl-tarfile "$deb" | tar -x -O -f - ./postinst 2>/dev/null || true
  done | sed -e ':a' -e '/\\$/{N;s/\\\n/ /;ba' -e '}' | tr '\t' ' ' |
    grep -oE 'update-alternatives +--install +[^ ]+ +[^ ]+ +[^ ]+ +[0-9]+' |
    awk '{print $3, $4, $5, $6}' | sort -k2,2 -k4,4nr | awk '!seen[$2]++ {print $1, $2, $3}' |
    while read -r link name path; do
      [ -e "$sysroot$path" ] || continue
      mkdir -p "$(dirname "$sysroot$link")"
      ln -snf "$(realpath -m --relative-to="$(dirname "$sysroot$link")" "$sysroot$path")" "$sysroot$link"
      say "alternative $name: $link -> $path"
    done
}

# CMake package files that name headers or libraries by an absolute /usr
# path (Ceres, OpenImageIO, Imath, OpenEXR, GTest, glog, ... in bookworm)
# would point the cross build at the host's amd64 files: those paths are
# put under ${CMAKE_SYSROOT}.
fix_cmake_files() {
  local f
  while IFS= read -r -d '' f; do
    if grep -qE '"/usr/lib/'"$multiarch"'/|[ ;"]/usr/include' "$f"; then
      sed -i -E 's#([ ;"(])/usr/(lib/'"$multiarch"'|include)#\1${CMAKE_SYSROOT}/usr/\2#g' "$f"
      say "sysroot prefix in ${f#"$sysroot"}"
    fi
  done < <(find "$sysroot/usr/lib/$multiarch/cmake" "$sysroot/usr/share" -maxdepth 3 -name '*.cmake' -print0 2>/dev/null)
}

# The symbols and shlibs files of the sysroot's packages, for dpkg-shlibdeps
# in `package`: $control/<package>/{symbols,shlibs}.
control="$sysroot/var/lib/propcam-control"
keep_control_files() {
  [ -f "$control/.done" ] && return
  local deb pkg tmp; tmp=$(mktemp -d)
  rm -rf "$control"; mkdir -p "$control"
  for deb in "$sysroot"/var/cache/apt/archives/*.deb; do
    rm -rf "${tmp:?}"/*
    dpkg-deb -e "$deb" "$tmp"
    [ -f "$tmp/symbols" ] || [ -f "$tmp/shlibs" ] || continue
    pkg=$(sed -n 's/^Package: //p' "$tmp/control")
    mkdir -p "$control/$pkg"
    cp "$tmp"/symbols "$tmp"/shlibs "$control/$pkg/" 2>/dev/null || true
  done
  rm -rf "$tmp"
  touch "$control/.done"
  say "symbols/shlibs files of $(ls "$control" | wc -l) library packages in ${control#"$here"/}"
}

make_sysroot() {
  local stamp="$sysroot/.propcam-sysroot" want
  want="bookworm arm64 ${sysroot_packages[*]}"
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    say "sysroot present: $sysroot"
  else
    rm -rf "$sysroot"
    # The host's Debian sources (bookworm, its mirror). The extract variant
    # unpacks the packages and their dependencies and runs nothing of them,
    # so no emulation is needed; the .deb files stay in var/cache/apt/archives
    # (the alternatives below, dpkg-shlibdeps's symbols files in `package`).
    local sources=/etc/apt/sources.list.d/debian.sources
    [ -f "$sources" ] || sources=/etc/apt/sources.list
    say "arm64 sysroot $sysroot: ${sysroot_packages[*]} and their dependencies"
    "${nice[@]}" mmdebstrap --quiet --variant=extract --architectures=arm64 \
      --include="$(IFS=,; echo "${sysroot_packages[*]}")" \
      --skip=cleanup/apt/cache --skip=check/qemu \
      bookworm "$sysroot" "$sources" >&2
    echo "$want" > "$stamp"
  fi
  if [ ! -f "$sysroot/.propcam-fixed" ]; then
    relativize_links
    make_alternatives
    fix_cmake_files
    keep_control_files
    touch "$sysroot/.propcam-fixed"
  fi
  say "sysroot: $(du -sh "$sysroot" | cut -f1), $(ls "$sysroot"/var/cache/apt/archives/*.deb | wc -l) packages"
}

cmd_setup() {
  local t0; t0=$(date +%s.%N)
  install_host_packages
  make_sysroot
  say "setup done in $(elapsed "$t0") s"
}

# ---------------------------------------------------------------- build
cmd_build() {
  [ -f "$sysroot/.propcam-sysroot" ] || { say "no sysroot: scripts/arm64.sh setup first"; exit 1; }
  local t0; t0=$(date +%s.%N)
  (cd "$here" && "${nice[@]}" cmake --preset arm64 >&2)
  say "configured in $(elapsed "$t0") s"
  t0=$(date +%s.%N)
  # The build preset's targets: propcam propcamd module_tests.
  (cd "$here" && "${nice[@]}" cmake --build --preset arm64 -j "${PROPCAM_ARM64_JOBS:-2}" >&2)
  say "built propcam propcamd module_tests in $(elapsed "$t0") s"
}

# ---------------------------------------------------------------- package
# The arm64 libraries are in the sysroot, not in the host's dpkg database,
# where dpkg-shlibdeps (and so CPack's CPACK_DEBIAN_PACKAGE_SHLIBDEPS) looks
# for their packages. So dpkg-shlibdeps runs here, on a tree laid out as if
# the library packages that propcam and propcamd need were being built
# beside them: debian/<package>/DEBIAN/{symbols,shlibs} from each .deb's
# control files (kept by `setup` in $control) and
# debian/<package>/<libdir>/<soname> linked into the sysroot. Its Depends go
# to cpack with -D, with the architecture.
shlibdeps() {
  local work="$build/shlibdeps" needed soname pkg dir b n=0 bins=()
  rm -rf "$work"; mkdir -p "$work/debian/propcam/DEBIAN" "$work/debian/propcam/usr/bin"
  printf 'Source: propcam\n\nPackage: propcam\nArchitecture: arm64\n' > "$work/debian/control"
  for b in "$@"; do
    cp "$b" "$work/debian/propcam/usr/bin/"
    bins+=("debian/propcam/usr/bin/$(basename "$b")")
  done
  needed=$(for b in "$@"; do aarch64-linux-gnu-readelf -d "$b"; done |
    sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p' | sort -u)
  for soname in $needed; do
    # symbols: "libfoo.so.1 libfoo1 #MINVER#"; shlibs: "libfoo 1 libfoo1 (>= 1.2)"
    for pkg in $( (grep -l "^$soname " "$control"/*/symbols 2>/dev/null
                   awk -v s="$soname" '($1 ".so." $2) == s { print FILENAME }' "$control"/*/shlibs) |
                 xargs -r -n1 dirname | xargs -r -n1 basename | sort -u); do
      for dir in lib/$multiarch usr/lib/$multiarch; do
        [ -e "$sysroot/$dir/$soname" ] || continue
        mkdir -p "$work/debian/$pkg/DEBIAN" "$work/debian/$pkg/$dir"
        cp "$control/$pkg"/* "$work/debian/$pkg/DEBIAN/"
        ln -sf "$sysroot/$dir/$soname" "$work/debian/$pkg/$dir/$soname"
        n=$((n + 1))
      done
    done
  done
  say "dpkg-shlibdeps: $(wc -w <<<"$needed") libraries needed, $n found in the sysroot's packages"
  (cd "$work" && DEB_HOST_ARCH=arm64 dpkg-shlibdeps -O $(printf -- '-e%s ' "${bins[@]}")) |
    sed -n 's/^shlibs:Depends=//p'
}

cmd_package() {
  [ -f "$build/CMakeCache.txt" ] || { say "no build: scripts/arm64.sh build first"; exit 1; }
  local t0; t0=$(date +%s.%N)
  "${nice[@]}" cmake --build "$build" --target propcam propcamd >&2
  say "propcam propcamd up to date in $(elapsed "$t0") s"
  local t1 depends extra; t1=$(date +%s.%N)
  depends=$(shlibdeps "$build/firmware/propcam" "$build/firmware/propcamd")
  # What board/CMakeLists.txt names beside the libraries (font, systemd).
  extra=$(sed -n 's/^set(CPACK_DEBIAN_PACKAGE_DEPENDS "\(.*\)")$/\1/p' "$build/CPackConfig.cmake")
  say "Depends: ${extra:+$extra, }$depends"
  rm -rf "$build/packages"
  (cd "$build" && "${nice[@]}" cpack -G DEB -B "$build/packages" \
    -D CPACK_DEBIAN_PACKAGE_ARCHITECTURE=arm64 \
    -D CPACK_DEBIAN_PACKAGE_SHLIBDEPS=OFF \
    -D "CPACK_DEBIAN_PACKAGE_DEPENDS=${extra:+$extra, }$depends" >&2)
  rm -rf "$build/packages/_CPack_Packages"
  local deb; deb=$(ls "$build"/packages/*.deb)
  say "packaged in $(elapsed "$t1") s (dpkg-shlibdeps, cpack): $deb"
  dpkg-deb -f "$deb" Package Version Architecture Depends >&2
  # The programs in it are arm64.
  local x; x=$(mktemp -d)
  dpkg-deb -x "$deb" "$x"
  file "$x"/usr/bin/* | sed "s#$x##" >&2
  rm -rf "$x"
  echo "$deb"
}

# ---------------------------------------------------------------- test
# Runs an arm64 program of the build under qemu-user, with the sysroot's
# loader and libraries.
emulate() { "${nice[@]}" "$qemu" -L "$sysroot" "$@"; }

timed() {  # timed LABEL COMMAND...: runs it, then prints LABEL and its wall time
  local label=$1 t0 rc=0; shift
  t0=$(date +%s.%N)
  "$@" || rc=$?
  say "$label: exit $rc, $(elapsed "$t0") s"
  return $rc
}

cmd_test() {
  [ -f "$build/CMakeCache.txt" ] || { say "no build: scripts/arm64.sh build first"; exit 1; }
  local t0 rc=0; t0=$(date +%s.%N)
  # The module test programs (capture, render, inference, ui_fb and their
  # hard-case programs: label module); ctest runs them through the
  # toolchain's CMAKE_CROSSCOMPILING_EMULATOR.
  "${nice[@]}" ctest --test-dir "$build" -L module -j "${PROPCAM_ARM64_JOBS:-2}" \
    --output-on-failure --output-junit arm64-module-tests.xml || rc=$?
  say "module tests under qemu-user: exit $rc, $(elapsed "$t0") s"

  # The command line under emulation: the data folder is the build tree's
  # share/propcam, as for a native build.
  local cli="$build/firmware/propcam" out="$build/cli"
  local photo="$here/board/virtual/photos/living_room.png"
  rm -rf "$out"; mkdir -p "$out"
  timed "propcam --version" emulate "$cli" --version || rc=$?
  timed "propcam props" emulate "$cli" props > "$out/props.txt" || rc=$?
  say "props: $(wc -l < "$out/props.txt") lines"
  timed "propcam infer" emulate "$cli" infer "$photo" -o "$out/scene" || rc=$?
  timed "propcam composite" emulate "$cli" composite "$photo" --scene "$out/scene" \
    --prop chair --at 330,390 --spp 4 -o "$out/composite.png" || rc=$?
  say "test done in $(elapsed "$t0") s"
  return $rc
}

case "${1:-}" in
  setup) cmd_setup ;;
  build) cmd_build ;;
  package) cmd_package ;;
  test) cmd_test ;;
  all) cmd_setup; cmd_build; cmd_package; cmd_test ;;
  *) sed -n '2,9p' "$0" >&2; exit 2 ;;
esac
