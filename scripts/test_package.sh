#!/usr/bin/env bash
# Installs PropCam's Debian package into an empty root and runs it from the
# installed files only:
#   scripts/test_package.sh [BUILD_DIR]
# 1. builds the package (scripts/package.sh BUILD_DIR);
# 2. checks its metadata: dependencies that this machine's apt can satisfy,
#    the maintainer scripts, /etc files as conffiles;
# 3. unpacks it into an empty folder (dpkg-deb -x: the files dpkg would put
#    on a board, without running its maintainer scripts on this machine);
# 4. hides the checkout and the build folder (a private mount namespace with
#    empty folders over them; where that is not allowed it says so and goes
#    on with them visible) and runs, with an empty environment:
#    propcam --version, propcamd --version, propcam props, and one composite
#    of the virtual board's photo, all from the unpacked root.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$(cd "${1:-$here/build/release}" && pwd)"
deb=$("$here/scripts/package.sh" "$build" | tail -n 1)
echo "test_package: built $deb ($(du -h "$deb" | cut -f1))"

work=$(mktemp -d /tmp/propcam-package.XXXXXX)
trap 'rm -rf "$work"' EXIT

# --- metadata -----------------------------------------------------------------
depends=$(dpkg-deb -f "$deb" Depends)
echo "test_package: Depends: $depends"
# (Debian ships Ceres as a static library: its solvers come in as libcholmod, glog...)
for lib in libopencv libembree3 libcholmod libopenimageio libcamera libgpiod fonts-dejavu-core; do
  if [[ "$depends" != *"$lib"* ]]; then echo "test_package: Depends lacks $lib" >&2; exit 1; fi
done
# Every dependency is satisfiable here (apt resolves the package as a file).
if ! apt-get install --simulate --no-install-recommends "$deb" >"$work/apt.log" 2>&1; then
  cat "$work/apt.log" >&2
  echo "test_package: apt cannot satisfy the package's dependencies" >&2
  exit 1
fi
dpkg-deb -e "$deb" "$work/control"
for script in postinst prerm postrm; do
  [[ -x "$work/control/$script" ]] || { echo "test_package: no $script" >&2; exit 1; }
done
for conffile in /etc/propcam/propcam.env /etc/propcam/propcamd.env /etc/propcam/boards/rpi/board.json; do
  grep -qx "$conffile" "$work/control/conffiles" || { echo "test_package: $conffile is not a conffile" >&2; exit 1; }
done

# --- unpack -------------------------------------------------------------------
root="$work/root"
dpkg-deb -x "$deb" "$root"
for f in usr/bin/propcam usr/bin/propcamd usr/share/propcam/inference/depth_db.bin \
         usr/share/propcam/board/virtual/board.json lib/systemd/system/propcam.service \
         lib/systemd/system/propcamd.service usr/lib/sysusers.d/propcam.conf \
         usr/lib/tmpfiles.d/propcam.conf lib/udev/rules.d/60-propcam.rules etc/propcam/boards/rpi/board.json; do
  [[ -e "$root/$f" ]] || { echo "test_package: the package has no /$f" >&2; exit 1; }
done
if grep -rl --binary-files=text -F "$here" "$root" >"$work/leaks"; then
  echo "test_package: these installed files name the checkout $here:" >&2
  cat "$work/leaks" >&2
  exit 1
fi

# --- run from the unpacked root, the checkout hidden ----------------------------
out="$work/out"
mkdir -p "$out"
cat >"$work/run.sh" <<RUN
set -euo pipefail
bin="$root/usr/bin"
cd "$out"
"\$bin/propcam" --version
"\$bin/propcamd" --version
"\$bin/propcam" props
"\$bin/propcam" composite "$root/usr/share/propcam/board/virtual/photos/living_room.png" \\
  --prop chair --at 330,390 --spp 2 -o "$out/composite.png" --json > "$out/composite.json"
test -s "$out/composite.png"
RUN
hide="mount -t tmpfs -o size=1m,mode=0755 none \"$here\""
if [[ "$build" != "$here"/* ]]; then hide="$hide && mount -t tmpfs -o size=1m none \"$build\""; fi
if unshare --mount true 2>/dev/null; then
  echo "test_package: running from $root with $here hidden"
  unshare --mount sh -c "$hide && test ! -e \"$here/CMakeLists.txt\" && \
    env -i PATH=/usr/bin:/bin HOME=\"$out\" bash \"$work/run.sh\""
else
  echo "test_package: cannot make a mount namespace here (not root?): running with $here visible"
  env -i PATH=/usr/bin:/bin HOME="$out" bash "$work/run.sh"
fi
grep -q '"prop"' "$out/composite.json" || { cat "$out/composite.json" >&2; exit 1; }
echo "test_package: the installed package ran: --version, props, composite ($(stat -c %s "$out/composite.png") bytes)"
