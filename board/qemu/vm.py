#!/usr/bin/env python3
"""Boots the qemu board and drives it from the host.

QEMU (TCG, never KVM: see README.md) boots fetch.sh's kernel with
build_initramfs.sh's initramfs; the guest's init chroots into the host's root
(9p, read-only) and runs GUEST_SCRIPT, which writes to OUT (a writable 9p share
at /run/vm in the guest). The guest asks the host for what only the host can
do over its second serial port (/dev/ttyS1), one line per request, answered
"ok" or "error <why>":

  shot NAME      screendump of what the screen shows -> OUT/NAME.png
  unplug         the USB stick is pulled (device_del), answered once it is gone
  plug [BPS]     a stick with the image --stick is plugged in (device_add),
                 its writes throttled to BPS bytes/s if given
  note TEXT      printed on the host

The console (ttyS0) goes to OUT/console.log. Exit status: the guest script's,
124 when --timeout ran out, 125 when the guest never reported an exit.
Stdlib only.
"""
import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

# The checkout (board/qemu/vm.py's grandparent): the guest keeps it visible.
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class Monitor:
    """QEMU's human monitor over a UNIX socket."""

    def __init__(self, path, deadline):
        while True:
            try:
                self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                self.sock.connect(path)
                break
            except OSError:
                self.sock.close()
                if time.time() > deadline:
                    raise
                time.sleep(0.05)
        self.lock = threading.Lock()
        self._read_prompt()

    def _read_prompt(self):
        data = b""
        while not data.endswith(b"(qemu) "):
            chunk = self.sock.recv(65536)
            if not chunk:
                raise EOFError("monitor closed")
            data += chunk
        return data.decode(errors="replace")

    def command(self, line):
        with self.lock:
            self.sock.sendall(line.encode() + b"\n")
            out = self._read_prompt()
        # The monitor echoes the command (with terminal escapes) before its answer.
        out = re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", out)
        lines = [l for l in out.replace("\r", "").split("\n")]
        return "\n".join(l for l in lines[1:] if l != "(qemu) ").strip()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kernel-dir", required=True, help="fetch.sh's output (holds vmlinux)")
    ap.add_argument("--initrd", required=True)
    ap.add_argument("--out", required=True, help="folder the guest writes to (created)")
    ap.add_argument("--run", required=True, help="guest script, an absolute path on the host")
    ap.add_argument("--stick", help="raw FAT image: the USB stick, plugged in at boot")
    ap.add_argument("--stick-write-bps", type=int, default=0, help="throttle the boot stick's writes")
    ap.add_argument("--timeout", type=float, default=240)
    ap.add_argument("--smp", type=int, default=2)
    ap.add_argument("--mem", type=int, default=1536)
    ap.add_argument("--append", default="", help="more kernel command line")
    ap.add_argument("--quiet", action="store_true", help="do not copy the console to stderr")
    ap.add_argument("--watch", type=float, default=0, help="also screendump OUT/watch.png every WATCH seconds")
    args = ap.parse_args()

    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    mon_path, ctl_path = os.path.join(out, "mon.sock"), os.path.join(out, "ctl.sock")
    for p in (mon_path, ctl_path):
        if os.path.exists(p):
            os.unlink(p)
    stick = os.path.abspath(args.stick) if args.stick else None
    cmd = ["timeout", "--foreground", "-k", "5", str(int(args.timeout)), "qemu-system-x86_64",
           "-accel", "tcg", "-cpu", os.environ.get("PROPCAM_VM_CPU", "max"), "-m", str(args.mem), "-smp", str(args.smp),
           "-display", "none", "-vga", "std", "-no-reboot", "-net", "none",
           "-serial", "stdio", "-serial", f"unix:{ctl_path},server=on,wait=off",
           "-monitor", f"unix:{mon_path},server=on,wait=off",
           "-virtfs", "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap",
           "-virtfs", f"local,path={out},mount_tag=out,security_model=none,multidevs=remap",
           "-device", "qemu-xhci,id=xhci",
           "-kernel", os.path.join(args.kernel_dir, "vmlinux"), "-initrd", args.initrd,
           "-append", "console=ttyS0 panic=-1 quiet loglevel=4 vt.global_cursor_default=0 "
                      f"propcam.run={args.run} propcam.keep={REPO_ROOT} {args.append}".strip()]
    plugs = [0]

    def stick_drive(n, bps):
        opts = f"if=none,id=stick{n},file={stick},format=raw,cache=writethrough"
        if bps:
            opts += f",throttling.bps-write={bps}"
        return opts

    if stick:
        cmd += ["-drive", stick_drive(0, args.stick_write_bps),
                "-device", "usb-storage,bus=xhci.0,drive=stick0,id=stick,removable=on"]
    started = time.time()
    deadline = started + args.timeout
    # QEMU and its timeout(1) in a process group of their own: stop() ends both.
    qemu = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)

    def stop(signum, _frame):
        try:
            os.killpg(qemu.pid, signal.SIGTERM)
            qemu.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(qemu.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        sys.exit(128 + signum)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    exit_rc = [None]
    log = open(os.path.join(out, "console.log"), "w", buffering=1)

    def console():
        for raw in qemu.stdout:
            line = raw.decode(errors="replace").rstrip("\r\n")
            log.write(line + "\n")
            if not args.quiet:
                print(f"[{time.time() - started:6.1f}] {line}", file=sys.stderr, flush=True)
            m = re.search(r"@@VM-EXIT (\d+)@@", line)
            if m:
                exit_rc[0] = int(m.group(1))

    reader = threading.Thread(target=console, daemon=True)
    reader.start()
    monitor = Monitor(mon_path, deadline)

    def handle(request):
        word, _, rest = request.partition(" ")
        if word == "shot":
            name = re.sub(r"[^A-Za-z0-9_.-]", "_", rest.strip()) or "screen"
            path = os.path.join(out, name + ".png")
            reply = monitor.command(f"screendump {path} -f png")
            if not os.path.exists(path):
                return f"error screendump: {reply}"
            print(f"vm: screendump {path}", file=sys.stderr, flush=True)
            return "ok"
        if word == "unplug":
            monitor.command("device_del stick")
            while re.search(r'id "stick"', monitor.command("info qtree")):
                time.sleep(0.1)
            print(f"vm: stick unplugged at {time.time() - started:.1f} s", file=sys.stderr, flush=True)
            return "ok"
        if word == "plug":
            if not stick:
                return "error no --stick"
            plugs[0] += 1
            bps = int(rest) if rest.strip() else 0
            reply = monitor.command("drive_add 0 " + stick_drive(plugs[0], bps))
            if "OK" not in reply:
                return "error drive_add: " + reply
            reply = monitor.command(f"device_add usb-storage,bus=xhci.0,drive=stick{plugs[0]},id=stick,removable=on")
            if reply:
                return "error device_add: " + reply
            print(f"vm: stick plugged at {time.time() - started:.1f} s", file=sys.stderr, flush=True)
            return "ok"
        if word == "note":
            print(f"vm: guest: {rest}", file=sys.stderr, flush=True)
            return "ok"
        return f"error unknown request {word}"

    def control():
        try:
            ctl = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            ctl.connect(ctl_path)
            buf = b""
            while True:
                chunk = ctl.recv(4096)
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    request = line.decode(errors="replace").strip()
                    if not request:
                        continue
                    try:
                        reply = handle(request)
                    except Exception as e:  # the guest hears of it, the run goes on
                        reply = f"error {e}"
                    ctl.sendall(reply.encode() + b"\n")
        except OSError:
            return

    threading.Thread(target=control, daemon=True).start()

    def watch():
        while qemu.poll() is None:
            time.sleep(args.watch)
            try:
                monitor.command(f"screendump {os.path.join(out, 'watch.png')} -f png")
            except (OSError, EOFError):
                return

    if args.watch > 0:
        threading.Thread(target=watch, daemon=True).start()
    rc = qemu.wait()
    reader.join(timeout=5)
    elapsed = time.time() - started
    if exit_rc[0] is not None:
        print(f"vm: guest exited {exit_rc[0]} after {elapsed:.1f} s", file=sys.stderr)
        return exit_rc[0]
    if rc == 124 or elapsed >= args.timeout:
        print(f"vm: timed out after {elapsed:.1f} s (console: {out}/console.log)", file=sys.stderr)
        return 124
    print(f"vm: QEMU exited {rc} without a guest exit after {elapsed:.1f} s (console: {out}/console.log)",
          file=sys.stderr)
    return 125


if __name__ == "__main__":
    sys.exit(main())
