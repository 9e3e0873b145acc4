#!/usr/bin/python3
"""A command's wall time alone and beside CPU-bound processes (a benchmark, not a test).

Runs COMMAND alternately alone and with BUSY other processes spinning on the CPU (default
one: on a 2-core machine, one core busy), REPEATS times each, and prints the median and
range of each and the ratio of the medians. With --baseline "CMD", the runs alone are of
CMD instead (e.g. the same command with --threads 1), so the ratio is COMMAND under load
against CMD alone. Alternating keeps the ratio meaningful on a machine whose speed drifts.
The figures go to bench/RESULTS.md.

  bench/under_load.py [--repeats 5] [--busy 1] [--baseline "CMD"] -- build/apps/subslam run --dataset DIR ...
"""
import argparse
import statistics
import subprocess
import sys
import time


def timed(cmd):
    start = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--busy", type=int, default=1, help="CPU-bound processes beside the loaded runs")
    parser.add_argument("--baseline", help="the command timed alone (default: COMMAND itself)")
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args()
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        parser.error("give the command after --")
    baseline = args.baseline.split() if args.baseline else cmd
    timed(cmd)  # warm-up: caches, page cache
    alone, loaded = [], []
    for _ in range(args.repeats):
        alone.append(timed(baseline))
        burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
        try:
            time.sleep(0.2)  # the burners are running
            loaded.append(timed(cmd))
        finally:
            for b in burners:
                b.kill()
                b.wait()
    for name, values in (("baseline alone" if args.baseline else "alone", alone), (f"beside {args.busy} busy", loaded)):
        print(f"{name:>16}: median {statistics.median(values):.3f} s (range {min(values):.3f}-{max(values):.3f})")
    print(f"{'ratio':>16}: {statistics.median(loaded) / statistics.median(alone):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
