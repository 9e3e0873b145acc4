#!/usr/bin/python3
"""Long runs (a benchmark, not a test): time per step and memory along a run.

Drives the `random` scenario — a square world of fixed size with a fixed set of landmarks,
so that the map stops growing once the world has been seen — for PATH_LENGTH metres (the
scenario takes about 10 steps per metre), once per configuration, and prints per tenth
of the run the steps, the wall time of that tenth per step and the resident memory at its
end (report.json's `time_seconds.cumulative_by_tenth_of_steps` and
`rss_kb_by_tenth_of_steps`). Flat time per step and flat memory where the map stops
growing are the goal; what grows with the run is named in bench/RESULTS.md.

  bench/soak.py [--path_length 100000] [--configs ekfslam,rbpf,rbpf+eif] [--tool build/apps/subslam]
"""
import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time

CONFIGS = {
    "ekfslam": ["--frontend", "ekfslam"],
    "rbpf": ["--frontend", "rbpf", "--backend", "none"],
    "rbpf+eif": ["--frontend", "rbpf", "--backend", "eif"],
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--path_length", type=float, default=100000.0, help="metres driven")
    parser.add_argument("--world_size", type=float, default=100.0)
    parser.add_argument("--landmarks", type=int, default=150)
    parser.add_argument("--configs", default="ekfslam,rbpf,rbpf+eif")
    parser.add_argument("--tool", default="build/apps/subslam")
    args = parser.parse_args()
    for name in args.configs.split(","):
        if name not in CONFIGS:
            sys.exit(f"soak.py: unknown configuration {name} (one of {', '.join(CONFIGS)})")
        out = tempfile.mkdtemp(prefix="subslam_soak_")
        cmd = [args.tool, "run", "--scenario", "random", "--path_length", str(args.path_length),
               "--world_size", str(args.world_size), "--landmarks", str(args.landmarks),
               "--quiet", "--progress=false", "--out", out] + CONFIGS[name]
        start = time.monotonic()
        subprocess.run(cmd, check=True)
        wall = time.monotonic() - start
        with open(f"{out}/report.json") as f:
            report = json.load(f)
        shutil.rmtree(out)
        steps = report["counts"]["steps"]
        times = report["time_seconds"]["cumulative_by_tenth_of_steps"]
        rss = report["rss_kb_by_tenth_of_steps"]
        print(f"\n{name}: {steps} steps, {report['counts']['landmarks']} landmarks, "
              f"{report['counts']['submaps']} local maps; estimator {report['time_seconds']['total']:.1f} s, "
              f"command {wall:.1f} s, peak {report['peak_rss_kb'] / 1024:.0f} MiB")
        print("| tenth | steps | µs per step in this tenth | resident MiB at its end |")
        print("| --- | --- | --- | --- |")
        previous = 0.0
        for k, (t, kb) in enumerate(zip(times, rss)):
            done = steps * (k + 1) // 10
            per_step = (t - previous) / (steps // 10) * 1e6
            print(f"| {k + 1} | {done} | {per_step:.1f} | {kb / 1024:.0f} |")
            previous = t
    cmd_line = " ".join(sys.argv)
    print(f"\n(command: {cmd_line})")


if __name__ == "__main__":
    main()
