#!/usr/bin/env bash
# Installs propcam, propcamd, their systemd units, sysusers and udev rules
# under DESTDIR (an image's root, or a temp folder in the tests).
#   DESTDIR=/mnt/image scripts/install_board_units.sh [BUILD_DIR]
# BUILD_DIR defaults to build/release. Installing onto this machine's own
# root needs DESTDIR=/ spelt out; nothing here runs systemctl or udevadm.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$here/build/release}"
if [[ -z "${DESTDIR:-}" ]]; then
  echo "install_board_units.sh: set DESTDIR (DESTDIR=/ for this machine's root)" >&2
  exit 2
fi
root="${DESTDIR%/}"

for exe in propcam propcamd; do
  if [[ ! -x "$build/firmware/$exe" ]]; then
    echo "install_board_units.sh: $build/firmware/$exe is not built" >&2
    exit 1
  fi
done

install -D -m 0755 "$build/firmware/propcam" "$root/usr/local/bin/propcam"
install -D -m 0755 "$build/firmware/propcamd" "$root/usr/local/bin/propcamd"
install -D -m 0644 "$here/board/systemd/propcamd.service" "$root/etc/systemd/system/propcamd.service"
install -D -m 0644 "$here/board/systemd/propcam.service" "$root/etc/systemd/system/propcam.service"
install -D -m 0644 "$here/board/systemd/propcam.sysusers.conf" "$root/etc/sysusers.d/propcam.conf"
install -D -m 0644 "$here/board/systemd/propcam.tmpfiles.conf" "$root/etc/tmpfiles.d/propcam.conf"
install -D -m 0644 "$here/board/udev/60-propcam.rules" "$root/etc/udev/rules.d/60-propcam.rules"
install -D -m 0644 "$here/board/systemd/README.md" "$root/usr/local/share/propcam/board/systemd/README.md"
for board in rpi usb-webcam; do
  install -D -m 0644 "$here/board/$board/board.json" "$root/usr/local/share/propcam/board/$board/board.json"
done
# The env files are the admin's: written once, never overwritten.
for env in propcamd propcam; do
  if [[ ! -e "$root/etc/propcam/$env.env" ]]; then
    install -D -m 0644 "$here/board/systemd/$env.env" "$root/etc/propcam/$env.env"
  fi
done
