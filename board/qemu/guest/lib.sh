# Sourced by the qemu board's guest scripts (run by guest/init in the chroot
# of the host's root, under bash). Sets up the board's devices and gives
# the scripts: vm REQUEST (ask the host, vm.py), press/hold BUTTON (gpio-sim),
# await_state LABEL SECONDS (the appliance's snapshots), the stick's mounts.
OUT=/run/vm
GPIO_SIM=/sys/kernel/config/gpio-sim/propcam
STICK_MOUNT=/run/media/propcam-stick

log() { echo "guest: $*"; }

vm_ctl_open() {
  stty -F /dev/ttyS1 raw -echo
  exec 3<>/dev/ttyS1
}

# vm REQUEST...: one request to the host; fails unless it answers ok.
vm() {
  echo "$*" >&3
  read -r vm_reply <&3
  [ "$vm_reply" = ok ] || { log "host refused '$*': $vm_reply"; return 1; }
}

# The five buttons as gpio-sim lines on one bank labelled propcam-buttons
# (board.json's chip and lines), held released (pulled up: active-low).
BUTTONS="shoot next prev ok back"
gpio_sim_setup() {
  mkdir "$GPIO_SIM" "$GPIO_SIM/bank0"
  echo 5 > "$GPIO_SIM/bank0/num_lines"
  echo propcam-buttons > "$GPIO_SIM/bank0/label"
  i=0
  for b in $BUTTONS; do
    mkdir "$GPIO_SIM/bank0/line$i"
    echo "propcam-$b" > "$GPIO_SIM/bank0/line$i/name"
    i=$((i + 1))
  done
  echo 1 > "$GPIO_SIM/live"
  GPIO_SIM_DEV=/sys/bus/platform/devices/$(cat "$GPIO_SIM/dev_name")/$(cat "$GPIO_SIM/bank0/chip_name")
  for i in 0 1 2 3 4; do echo pull-up > "$GPIO_SIM_DEV/sim_gpio$i/pull"; done
}

button_line() {
  i=0
  for b in $BUTTONS; do
    [ "$b" = "$1" ] && { echo "$GPIO_SIM_DEV/sim_gpio$i/pull"; return; }
    i=$((i + 1))
  done
  log "no button $1"; return 1
}

# pause SECONDS without starting a process: a sleep(1) can take most of a
# second to start in the emulated guest, which would turn a press into a long
# press. (bash's read -t on a FIFO nobody writes.)
mkfifo /tmp/.pause.fifo
exec 7<> /tmp/.pause.fifo
pause() { read -r -t "$1" <&7 || true; }

# press BUTTON / hold BUTTON SECONDS: the line pulled down (pressed), then up.
press() { hold "$1" 0.15; }
hold() {
  f=$(button_line "$1") || return 1
  echo pull-down > "$f"; pause "$2"; echo pull-up > "$f"
  pause 0.3
}

# udevd for libcamera: its device enumerator (libudev) lists only the media
# and video4linux devices udevd has initialised (/run/udev/data), so without
# udevd it sees no camera. The host's systemd-udevd (package udev) handles
# just those two subsystems; udevadm would ignore requests in a chroot (the
# guest's init chroots) without SYSTEMD_IGNORE_CHROOT.
udev_start() {
  [ -x /lib/systemd/systemd-udevd ] || { log "no systemd-udevd (apt-get install udev: scripts/setup.sh)"; return 1; }
  SYSTEMD_IGNORE_CHROOT=1 /lib/systemd/systemd-udevd --daemon &&
    SYSTEMD_IGNORE_CHROOT=1 udevadm trigger --action=add --subsystem-match=media --subsystem-match=video4linux &&
    SYSTEMD_IGNORE_CHROOT=1 udevadm settle --timeout=60
}
udev_stop() { SYSTEMD_IGNORE_CHROOT=1 udevadm control --exit; }

# The framebuffer console must not draw over the appliance.
unbind_fbcon() {
  for f in /sys/class/vtconsole/vtcon*/bind; do echo 0 > "$f" 2>/dev/null; done
  true
}

# A stick appears as /dev/sdX: check it (fsck.vfat -a) and mount it (vfat) at $STICK_MOUNT; a stick that
# went away is unmounted (lazily: its files may still be open). Runs in the
# background, like udisks on a desktop.
stick_watch() {
  mkdir -p "$STICK_MOUNT"
  mounted=
  while :; do
    if [ -n "$mounted" ] && [ ! -e "/sys/block/$mounted" ]; then
      umount -l "$STICK_MOUNT" && log "stick $mounted gone, unmounted"
      mounted=
    fi
    if [ -z "$mounted" ]; then
      for d in /sys/block/sd*; do
        [ -e "$d" ] || continue
        n=${d##*/}
        # A stick pulled mid-write can come back with a FAT the kernel then
        # turns read-only ("deleting FAT entry beyond EOF"): repair it first,
        # as a desktop's fsck would.
        fsck.vfat -a "/dev/$n" > /dev/null 2>&1
        if mount -t vfat -o flush "/dev/$n" "$STICK_MOUNT" 2>/dev/null; then mounted=$n; log "stick $n mounted"; break; fi
      done
    fi
    sleep 0.2
  done
}

# await_state LABEL SECONDS: waits (SECONDS of guest uptime) for the
# appliance's next snapshot named NNN-LABEL.png in $SNAPSHOTS after the last
# one awaited.
SNAPSHOTS=/tmp/snapshots
last_snapshot=0
await_state() {
  read -r now _ < /proc/uptime
  deadline=$((${now%.*} + $2))
  while :; do
    for f in "$SNAPSHOTS"/*-"$1".png; do
      [ -e "$f" ] || continue
      n=${f##*/}; n=${n%%-*}; n=${n#0}; n=${n#0}
      if [ "$n" -gt "$last_snapshot" ]; then last_snapshot=$n; return 0; fi
    done
    read -r now _ < /proc/uptime
    [ "${now%.*}" -lt "$deadline" ] || break
    sleep 0.1
  done
  log "timed out after $2 s waiting for state $1 (have: $(ls "$SNAPSHOTS" 2>/dev/null | tr '\n' ' '))"
  return 1
}
