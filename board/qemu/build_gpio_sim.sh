#!/usr/bin/env bash
# Builds gpio-sim (not enabled in bookworm's kernels) out of tree as one
# module, gpio-sim.ko: drivers/gpio/gpio-sim.c and kernel/irq/irq_sim.c from
# linux-source, against the matching linux-headers that fetch.sh unpacked.
# irq_to_desc is not exported to modules, so irq_sim's one call
# handle_simple_irq(irq_to_desc(irq)) becomes generic_handle_irq(irq).
# Usage: build_gpio_sim.sh KERNEL_DIR (fetch.sh's output). Prints the .ko.
set -euo pipefail
kdir=$(cd "$1" && pwd)
kver=$(cat "$kdir/kver")
abi=${kver%-amd64}
out=$kdir/gpio-sim
if [ -f "$out/gpio-sim.ko" ]; then echo "$out/gpio-sim.ko"; exit 0; fi
hdr=$kdir/root/usr/src/linux-headers-$kver
# The headers' Makefile includes the common half by its installed path; point it at ours.
echo "include $kdir/root/usr/src/linux-headers-$abi-common/Makefile" > "$hdr/Makefile"
rm -rf "$out.tmp"; mkdir -p "$out.tmp"
cp "$kdir/src/drivers/gpio/gpio-sim.c" "$out.tmp/gpio-sim-main.c"
cp "$kdir/src/drivers/gpio/gpiolib.h" "$out.tmp/"
sed 's/handle_simple_irq(irq_to_desc(irqnum))/generic_handle_irq(irqnum)/' "$kdir/src/kernel/irq/irq_sim.c" > "$out.tmp/irq_sim.c"
grep -q 'generic_handle_irq(irqnum)' "$out.tmp/irq_sim.c" || { echo "build_gpio_sim: irq_sim.c changed, patch did not apply" >&2; exit 1; }
cat > "$out.tmp/Kbuild" <<'KB'
obj-m := gpio-sim.o
gpio-sim-y := gpio-sim-main.o irq_sim.o
KB
make -s -C "$hdr" M="$out.tmp" modules >&2
rm -rf "$out"; mv "$out.tmp" "$out"
echo "$out/gpio-sim.ko"
