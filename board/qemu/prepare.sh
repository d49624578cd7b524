#!/usr/bin/env bash
# Everything the qemu board boots, from Debian's archive into the cache
# ($PROPCAM_QEMU_CACHE, default build/qemu): the kernel (fetch.sh), gpio-sim
# (build_gpio_sim.sh), vimc (build_vimc.sh) and the initramfs (build_initramfs.sh, rebuilt when
# guest/init or the script changed). Prints two lines: the kernel folder and
# the initramfs. A second run reuses the cache (about a second).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cache=${PROPCAM_QEMU_CACHE:-$here/../../build/qemu}
mkdir -p "$cache"
kdir=$(PROPCAM_QEMU_CACHE=$cache "$here/fetch.sh")
"$here/build_gpio_sim.sh" "$kdir" > /dev/null
vimc_ko=$("$here/build_vimc.sh" "$kdir")
initrd=$kdir/initrd.cpio.gz
if [ ! -f "$initrd" ] || [ "$here/guest/init" -nt "$initrd" ] || [ "$here/build_initramfs.sh" -nt "$initrd" ] ||
   [ "$vimc_ko" -nt "$initrd" ]; then
  "$here/build_initramfs.sh" "$kdir" "$initrd" > /dev/null
fi
echo "$kdir"
echo "$initrd"
