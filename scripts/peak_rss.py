#!/usr/bin/env python3
"""Peak resident memory of every test in a ctest label, one process at a time.

Each test's command (as ctest would run it) is started alone and reaped with
wait4, whose rusage gives the peak of the process and of every child it
waited for (a test that runs the `propcam` CLI counts the CLI's peak too).
Prints a table sorted by peak and a summary against a budget.

    scripts/peak_rss.py --build build/release --label hard_case --budget-mb 512 --out build/peak_rss_hard_case.tsv
"""
import argparse
import json
import os
import subprocess
import sys
import time


def tests_of(build, label):
    listing = subprocess.run(["ctest", "--test-dir", build, "-L", label, "--show-only=json-v1"],
                             check=True, capture_output=True, text=True).stdout
    for test in json.loads(listing)["tests"]:
        props = {p["name"]: p["value"] for p in test.get("properties", [])}
        yield test["name"], test["command"], props.get("WORKING_DIRECTORY", build), props.get("ENVIRONMENT", [])


def run_one(command, cwd, environment, timeout_s):
    env = dict(os.environ)
    for item in environment:
        key, _, value = item.partition("=")
        env[key] = value
    start = time.monotonic()
    proc = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() - start > timeout_s:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = -9
            return None, time.monotonic() - start, usage.ru_maxrss / 1024.0
        time.sleep(0.02)
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
    return proc.returncode, time.monotonic() - start, usage.ru_maxrss / 1024.0


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default="build/release")
    parser.add_argument("--label", default="hard_case")
    parser.add_argument("--budget-mb", type=float, default=512.0)
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds per test")
    parser.add_argument("--out", help="also write the table here (TSV)")
    args = parser.parse_args()

    rows = []
    for name, command, cwd, environment in tests_of(args.build, args.label):
        code, seconds, peak_mb = run_one(command, cwd, environment, args.timeout)
        rows.append((peak_mb, seconds, "timeout" if code is None else str(code), name))
        print(f"{peak_mb:8.1f} MB {seconds:7.2f} s  exit {rows[-1][2]:>7}  {name}", file=sys.stderr, flush=True)
    rows.sort(reverse=True)
    lines = ["peak_mb\tseconds\texit\ttest"] + [f"{p:.1f}\t{s:.2f}\t{c}\t{n}" for p, s, c, n in rows]
    if args.out:
        with open(args.out, "w") as f:
            f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    over = [r for r in rows if r[0] > args.budget_mb]
    failed = [r for r in rows if r[2] != "0"]
    print(f"# {len(rows)} tests of label {args.label}: peak {rows[0][0]:.1f} MB ({rows[0][3]}), "
          f"median {rows[len(rows) // 2][0]:.1f} MB; {len(over)} over {args.budget_mb:.0f} MB; "
          f"{len(failed)} did not exit 0")
    return 1 if over or failed else 0


if __name__ == "__main__":
    sys.exit(main())
