# The qemu board's system test session (bash), one boot (vm.py --run): what
# tests/qemu/qemu_board_test.cpp checks is left in /run/vm.
#   1. propcamd on vivid (the V4L2 backend), a still through it: shot.png;
#      a second propcamd on vimc (the libcamera backend, libcamera:auto as on
#      the Pi), a still through it while the appliance starts: vimc.png
#   2.-4. the appliance (propcam run --daemon, board/qemu/board.json): buttons
#      as gpio-sim line pulls, screendumps of the viewfinder, the carousel and
#      the converged composite; a long OK exports while the (write-throttled)
#      stick is pulled mid-export; the stick comes back and the spool is
#      flushed onto it. run.json, run.log, snapshots/, stick.txt.
#   5. the console: back in text mode after the appliance, and taken and
#      restored (after a crash too) by ui_fb's Console tests: console_tests.txt.
# /run/vm/env.sh (written by the host) sets PROPCAM_BIN (the build folder)
# and may set PROPCAM_DATA (a data folder with thumbnails to start from).
. "$(dirname "$0")/lib.sh"
. "$OUT/env.sh"
set -u
step() { read -r up _ < /proc/uptime; log "[$up] $*"; echo "$up $*" >> "$OUT/steps.txt"; }
propcam=$PROPCAM_BIN/firmware/propcam
propcamd=$PROPCAM_BIN/firmware/propcamd
board=$(cd "$(dirname "$0")/.." && pwd)/board.json

vm_ctl_open
gpio_sim_setup
unbind_fbcon
stick_watch > "$OUT/stick_watch.log" 2>&1 &
watcher=$!
# vivid: no on-screen text, so its frames are its 75% colour bars only.
v4l2-ctl -d /dev/video0 -c osd_text_mode=2
step devices ready

# 1. propcamd on vivid, and a still through its socket.
mkdir -p /run/propcam
"$propcamd" --socket /run/propcam/capture.sock --camera v4l2:/dev/video0 --width 320 --height 180 --format YUYV --fps 10 \
  > "$OUT/propcamd.log" 2>&1 &
daemon=$!
# (Every propcam process costs tens of seconds of dynamic linking under TCG:
# the camera list runs beside the rest.) udevd first, beside propcamd's start:
# libcamera enumerates once, when a process starts it; udev.done marks it settled.
{
  udev_start > "$OUT/udev.log" 2>&1 || log "udevd failed: libcamera will see no camera"
  : > /run/propcam/udev.done
  step udevd settled
  "$propcam" cameras --json > "$OUT/cameras.json" 2> "$OUT/cameras.log"
} &
cameras=$!
t=0
until [ -S /run/propcam/capture.sock ]; do
  pause 0.2; t=$((t + 1))
  [ "$t" -lt 3000 ] || { log "propcamd never served its socket"; break; }
done
step propcamd serving
# vimc's propcamd links while the vivid still is taken (the dynamic linker
# keeps one vCPU busy, the other is free). 960x540: vimc's scaler triples the
# sensor's size, so a side that is no multiple of 3 would be adjusted; the
# still is larger than the viewfinder, as on the Pi (the stream restarts).
t=0
until [ -e /run/propcam/udev.done ]; do
  pause 0.2; t=$((t + 1))
  [ "$t" -lt 600 ] || { log "udevd never settled"; break; }
done
"$propcamd" --socket /run/propcam/vimc.sock --camera libcamera:auto --width 960 --height 540 --format RGB24 \
  > "$OUT/propcamd_vimc.log" 2>&1 &
vimc_daemon=$!
"$propcam" shoot --daemon /run/propcam/capture.sock --still-size 320x180 --settle-frames 4 -o "$OUT/shot.png" --json \
  > "$OUT/shoot.json" 2> "$OUT/shoot.log"
echo $? > "$OUT/shoot.rc"
step shot through propcamd
# The vimc still, beside the appliance's start (linking, again one vCPU).
vimc_still() {
  t=0
  until [ -S /run/propcam/vimc.sock ]; do
    kill -0 "$vimc_daemon" 2> /dev/null || { log "vimc's propcamd ended"; break; }
    pause 0.2; t=$((t + 1))
    [ "$t" -lt 1500 ] || { log "vimc's propcamd never served its socket"; break; }
  done
  "$propcam" shoot --daemon /run/propcam/vimc.sock --still-size 1920x1080 --settle-frames 2 -o "$OUT/vimc.png" --json \
    > "$OUT/shoot_vimc.json" 2> "$OUT/shoot_vimc.log"
  echo $? > "$OUT/shoot_vimc.rc"
  kill -TERM "$vimc_daemon"
  step vimc still through propcamd
}
vimc_still &
vimc=$!

# 2.-4. the appliance.
data=/run/propcam/data
mkdir -p "$data"
[ -n "${PROPCAM_DATA:-}" ] && cp -r "$PROPCAM_DATA"/. "$data"/
"$propcam" run --board "$board" --daemon /run/propcam/capture.sock --snapshots "$SNAPSHOTS" --data "$data" \
  --threads 2 --json > "$OUT/run.json" 2> "$OUT/run.log" &
app=$!
# The vimc still is done before the first press (nothing else runs while
# presses are timed); udevd is not needed after it.
wait "$vimc"; wait "$vimc_daemon"; echo $? > "$OUT/propcamd_vimc.rc"
udev_stop
ok=1
session() {
  await_state viewfinder 600 || return 1
  gpioinfo propcam-buttons > "$OUT/gpioinfo.txt"
  vm shot viewfinder || return 1
  step viewfinder
  press shoot
  await_state placing-prop 900 || return 1
  vm shot carousel || return 1
  step carousel
  # The cube: three PREVs from the first prop; the first spot; the draft tier.
  press prev; press prev; press prev
  press ok
  await_state placing-spot 600 || return 1
  press ok
  await_state placing-tier 600 || return 1
  press prev
  press ok
  await_state rendering 600 || return 1
  await_state adjusting 900 || return 1
  vm shot composite || return 1
  step converged
  # Export (long OK); pull the stick while the export's files are being written.
  hold ok 1.2
  t=0
  until compgen -G "$STICK_MOUNT/PropCam/.propcam-*" > /dev/null; do
    pause 0.05; t=$((t + 1))
    [ "$t" -lt 2400 ] || { log "no export started on the stick"; return 1; }
  done
  ls -la "$STICK_MOUNT"/PropCam > "$OUT/stick_at_unplug.txt" 2>&1
  vm unplug || return 1
  step unplugged mid-export
  await_state adjusting 600 || return 1
  vm shot spooled || return 1
  ls -R /run/propcam/spool > "$OUT/spool_unplugged.txt" 2>&1
  vm plug || return 1
  step plugged back
  # The appliance flushes the spool onto the stick by itself.
  t=0
  until compgen -G "$STICK_MOUNT/PropCam/*.png" > /dev/null && ! compgen -G "/run/propcam/spool/*" > /dev/null; do
    pause 0.2; t=$((t + 1))
    [ "$t" -lt 600 ] || { log "the spool was not flushed to the stick"; return 1; }
  done
  step flushed
  vm shot flushed || return 1
}
session || ok=0
kill -TERM "$app"; wait "$app"; echo $? > "$OUT/run.rc"
wait "$cameras"
kill -TERM "$daemon"; wait "$daemon"
# The console: ui_fb's Console tests start by requiring the VT in text mode
# (the appliance must have given it back on SIGTERM), then take it and have
# a child crash holding it, on this real VT.
"$PROPCAM_BIN/tests/ui_fb_tests" --gtest_filter='Console.*' > "$OUT/console_tests.txt" 2>&1
echo $? > "$OUT/console_tests.rc"
cp -r "$SNAPSHOTS" "$OUT/snapshots"
ls -la "$STICK_MOUNT"/PropCam > "$OUT/stick.txt" 2>&1
ls -A /run/propcam/spool > "$OUT/spool.txt" 2>&1
kill "$watcher"
sync
umount "$STICK_MOUNT" 2>/dev/null
step done ok=$ok
[ "$ok" = 1 ]
