#!/usr/bin/env bash
# Builds vimc (CONFIG_VIDEO_VIMC is not set in bookworm's kernels) out of
# tree: drivers/media/test-drivers/vimc from linux-source, unchanged, against
# the matching linux-headers that fetch.sh unpacked. libcamera has a pipeline
# handler (and an IPA module) for it: the qemu board's libcamera camera.
# Usage: build_vimc.sh KERNEL_DIR (fetch.sh's output). Prints the .ko.
set -euo pipefail
kdir=$(cd "$1" && pwd)
kver=$(cat "$kdir/kver")
abi=${kver%-amd64}
out=$kdir/vimc
if [ -f "$out/vimc.ko" ]; then echo "$out/vimc.ko"; exit 0; fi
src=$kdir/src/drivers/media/test-drivers/vimc
[ -f "$src/Makefile" ] || { echo "build_vimc: $src missing (fetch.sh)" >&2; exit 1; }
hdr=$kdir/root/usr/src/linux-headers-$kver
# The headers' Makefile includes the common half by its installed path; point it at ours.
echo "include $kdir/root/usr/src/linux-headers-$abi-common/Makefile" > "$hdr/Makefile"
rm -rf "$out.tmp"; cp -r "$src" "$out.tmp"
make -s -C "$hdr" M="$out.tmp" CONFIG_VIDEO_VIMC=m modules >&2
rm -rf "$out"; mv "$out.tmp" "$out"
echo "$out/vimc.ko"
