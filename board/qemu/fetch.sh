#!/usr/bin/env bash
# Fetches, from Debian's archive through apt (apt-get download, no root
# needed), the kernel the qemu board boots and what gpio-sim is built from:
#   linux-image-<kver>       the kernel linux-image-amd64 depends on today
#   linux-headers-<kver>, linux-headers-<abi>-common, linux-kbuild-<x.y>
#   linux-source-<x.y>       only gpio-sim.c, gpiolib.h, irq_sim.c and vimc's
#                            folder are kept
# into the cache ($PROPCAM_QEMU_CACHE, default build/qemu), unpacks the image
# (modules.dep by depmod) and the uncompressed vmlinux (PVH entry: boots in
# half the time of the bzImage under TCG). Idempotent: a second run with the
# same kernel does nothing (a cache from before vimc only gets its sources).
# Prints the cache's kernel folder.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=${PROPCAM_QEMU_CACHE:-$here/../../build/qemu}
mkdir -p "$cache/debs"
cache=$(cd "$cache" && pwd)

image_pkg=$(apt-cache depends linux-image-amd64 | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
[ -n "$image_pkg" ] || { echo "fetch: apt-cache knows no linux-image-amd64 (apt-get update?)" >&2; exit 1; }
kver=${image_pkg#linux-image-}          # 6.1.0-57-amd64
abi=${kver%-amd64}                      # 6.1.0-57
series=$(echo "$kver" | cut -d. -f1-2)  # 6.1
kdir=$cache/kernel-$kver

# The out-of-tree modules' sources (build_gpio_sim.sh, build_vimc.sh) from
# the linux-source tarball into DIR.
extract_sources() {
  local srcdeb
  srcdeb=$(ls "$cache/debs/linux-source-${series}"_*.deb | head -1)
  dpkg-deb --fsys-tarfile "$srcdeb" | tar -x -O "./usr/src/linux-source-$series.tar.xz" |
    tar -xJ -C "$1" --strip-components=1 \
      "linux-source-$series/drivers/gpio/gpio-sim.c" "linux-source-$series/drivers/gpio/gpiolib.h" \
      "linux-source-$series/kernel/irq/irq_sim.c" "linux-source-$series/drivers/media/test-drivers/vimc"
}
vimc_src=src/drivers/media/test-drivers/vimc
if [ -f "$kdir/.complete" ]; then
  if [ ! -d "$kdir/$vimc_src" ]; then
    echo "fetch: vimc's sources from linux-source-$series" >&2
    rm -rf "$kdir/src.tmp"; mkdir -p "$kdir/src.tmp"
    extract_sources "$kdir/src.tmp"
    cp -r "$kdir/src.tmp/drivers/media" "$kdir/src/drivers/" && rm -rf "$kdir/src.tmp"
  fi
  echo "$kdir"; exit 0
fi

cd "$cache/debs"
pkgs=("$image_pkg" "linux-headers-$kver" "linux-headers-$abi-common" "linux-kbuild-$series" "linux-source-$series")
need=()
for p in "${pkgs[@]}"; do ls "${p}"_*.deb >/dev/null 2>&1 || need+=("$p"); done
if ((${#need[@]})); then
  echo "fetch: apt-get download ${need[*]}" >&2
  apt-get download "${need[@]}" >&2
fi

rm -rf "$kdir.tmp"; mkdir -p "$kdir.tmp/root" "$kdir.tmp/src"
for p in "$image_pkg" "linux-headers-$kver" "linux-headers-$abi-common" "linux-kbuild-$series"; do
  dpkg-deb -x "$(ls "${p}"_*.deb | head -1)" "$kdir.tmp/root"
done
depmod -b "$kdir.tmp/root" "$kver"
# vmlinux: the xz stream inside the bzImage (its magic FD 37 7A 58 5A 00).
vmlinuz=$kdir.tmp/root/boot/vmlinuz-$kver
offset=$(LC_ALL=C grep -abo $'\xfd7zXZ\x00' "$vmlinuz" | head -1 | cut -d: -f1)
tail -c +$((offset + 1)) "$vmlinuz" | xz -dc --single-stream > "$kdir.tmp/vmlinux" 2>/dev/null || true
head -c 4 "$kdir.tmp/vmlinux" | grep -q $'\x7fELF' || { echo "fetch: no vmlinux in $vmlinuz" >&2; exit 1; }
extract_sources "$kdir.tmp/src"
echo "$kver" > "$kdir.tmp/kver"
touch "$kdir.tmp/.complete"
rm -rf "$kdir"; mv "$kdir.tmp" "$kdir"
echo "$kdir"
