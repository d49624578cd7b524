"""`propcam render` as the Blender scripts call it, adapting to what the binary's
`propcam render --help` says (the CLI is changing): the meaning of --bounces
and whether --threads and --clamp exist. No Blender import."""
import functools
import json
import os
import re
import subprocess
import time


@functools.lru_cache(maxsize=None)
def render_help(propcam):
    return subprocess.run([propcam, "render", "--help"], capture_output=True, text=True).stdout


def _option_text(help_text, name):
    """The help of option `name`: its line and the indented lines after it."""
    m = re.search(r"^\s*(?:-\w,)?%s\b.*(?:\n\s{20,}\S.*)*" % re.escape(name), help_text, re.M)
    return m.group(0) if m else ""


def has_option(propcam, name):
    return bool(_option_text(render_help(propcam), name))


def bounces_like_cycles(propcam):
    """True once --bounces counts as Cycles' max_bounces (0 = direct light
    only); before, Cycles B was our B + 1 (docs/blender_world.md)."""
    return bool(re.search(r"direct|cycles", _option_text(render_help(propcam), "--bounces"), re.I))


def bounces_arg(propcam, cycles_bounces):
    return cycles_bounces if bounces_like_cycles(propcam) else cycles_bounces + 1


def threads_note(propcam, threads):
    if has_option(propcam, "--threads"):
        return "--threads %d" % threads
    if threads < (os.cpu_count() or 1):
        return "no --threads: pinned to %d CPU(s) by taskset (it starts one thread per hardware thread)" % threads
    return "no --threads: all %d hardware threads" % (os.cpu_count() or 1)


def clamp_note(propcam):
    if has_option(propcam, "--clamp"):
        return "off (--clamp 0)"
    return "luminance 64 per sample (this binary has no --clamp)"


def render(propcam, scene, out, spp, cycles_bounces, seed, threads, time_budget=None):
    """Runs `propcam render --json`; returns its summary plus `wall_s` (the
    whole process: loading, BVH build, rendering, writing)."""
    cmd = [propcam, "render", scene, "-o", out, "--json", "--seed", str(seed),
           "--bounces", str(bounces_arg(propcam, cycles_bounces))]
    cmd += ["--time", str(time_budget)] if time_budget else ["--spp", str(spp)]
    if has_option(propcam, "--threads"):
        cmd += ["--threads", str(threads)]
    elif threads < (os.cpu_count() or 1):
        cmd = ["taskset", "-c", "0-%d" % (threads - 1)] + cmd
    if has_option(propcam, "--clamp"):
        cmd += ["--clamp", "0"]  # no per-sample clamp: Cycles' clamps are off too
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError("%s failed (exit %d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-2000:]))
    summary = json.loads(r.stdout[r.stdout.index("{"):])
    summary["wall_s"] = wall
    summary["command"] = cmd
    return summary
