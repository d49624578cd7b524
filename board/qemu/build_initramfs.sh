#!/usr/bin/env bash
# Builds the qemu board's initramfs: static busybox, the kernel modules the
# board needs (with their dependencies, in load order), gpio-sim.ko,
# vimc.ko and guest/init. The init mounts the host's root read-only over 9p and chroots
# into it, so the guest runs the host-built propcam binaries and libraries.
# Usage: build_initramfs.sh KERNEL_DIR OUT.cpio.gz
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
kdir=$(cd "$1" && pwd)
out=$2
kver=$(cat "$kdir/kver")
ko=$kdir/gpio-sim/gpio-sim.ko
[ -f "$ko" ] || { echo "build_initramfs: $ko missing (build_gpio_sim.sh)" >&2; exit 1; }
vimc_ko=$kdir/vimc/vimc.ko
[ -f "$vimc_ko" ] || { echo "build_initramfs: $vimc_ko missing (build_vimc.sh)" >&2; exit 1; }
busybox=$(command -v busybox || true)
if [ -z "$busybox" ] || ldd "$busybox" >/dev/null 2>&1; then
  echo "build_initramfs: a static busybox is needed (apt-get install busybox-static)" >&2; exit 1
fi
# The board's drivers; everything else (configfs, the console) is built in or pulled in.
modules=(configfs virtio_pci 9pnet_virtio 9p vivid bochs xhci_pci usb_storage sd_mod vfat nls_cp437 nls_iso8859_1 nls_utf8 nls_ascii)
# vimc's in-tree dependencies (videobuf2, v4l2-tpg, mc): loaded before it.
IFS=, read -r -a vimc_deps <<< "$(modinfo -F depends "$vimc_ko")"
modules+=("${vimc_deps[@]}")
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
mkdir -p "$root"/{bin,dev,proc,sys,host,modules}
cp "$busybox" "$root/bin/busybox"
for a in sh mount umount mkdir insmod echo cat sleep poweroff ls chroot; do ln -s busybox "$root/bin/$a"; done
n=0
for m in "${modules[@]}"; do
  modprobe -d "$kdir/root" -S "$kver" --show-depends "$m" | awk '$1 == "insmod" {print $2}'
done | awk '!seen[$0]++' | while read -r f; do
  n=$((n + 1)); base=$(basename "$f")
  cp "$f" "$root/modules/$(printf %02d "$n")-$base"
done
# vimc after vivid, so that vivid stays /dev/video0.
cp "$vimc_ko" "$root/modules/98-vimc.ko"
cp "$ko" "$root/modules/99-gpio-sim.ko"
cp "$here/guest/init" "$root/init"; chmod +x "$root/init"
(cd "$root" && find . | LC_ALL=C sort | cpio -o -H newc --quiet | gzip -1) > "$out.tmp"
mv "$out.tmp" "$out"
echo "$out"
