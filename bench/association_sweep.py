#!/usr/bin/env python3
"""Back-end association over many runs: duplicates, wrong merges, accuracy.

Runs `subslam run` (and `subslam join` on the recorded local maps) over seeds and
settings, two processes at a time, and prints one markdown table per sweep. Each run
uses --threads 1 (results do not depend on the thread count).

  bench/association_sweep.py hybrid   [--seeds 1-20]   # HybridSLAM Table 1's four (alpha, beta)
  bench/association_sweep.py combined [--seeds 1-20]   # combined-2km, RBPF maps, revision on/off
  bench/association_sweep.py victoria [--seeds 1-8]    # Victoria Park, filter seeds, no calibration
  bench/association_sweep.py backends [--seeds 1-20]   # every joining back-end on combined-2km's RBPF maps

Options: --bin PATH (default build/apps/subslam), --out DIR (default /tmp/subslam_sweep),
--jobs N (default 2), extra flags after `--` go to every run.
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def seeds(text):
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}\n{p.stderr[-2000:]}")


def report(path):
    with open(os.path.join(path, "report.json")) as f:
        return json.load(f)


def pool(args, jobs):
    jobs = [j for j in jobs if not (args.reuse and os.path.exists(os.path.join(j[j.index("--out") + 1], "report.json")))]
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as ex:
        for f in [ex.submit(run, j) for j in jobs]:
            f.result()


def hybrid(args):
    settings = [(1.0, 0.00), (0.7, 0.02), (0.4, 0.04), (0.1, 0.06)]
    jobs, cells = [], []
    for a, b in settings:
        for s in args.seeds:
            for known in (False, True):
                out = os.path.join(args.out, f"hybrid_a{a}_b{b}_s{s}_{'known' if known else 'est'}")
                cmd = [args.bin, "run", "--scenario", "hybrid-120m", "--seed", str(s), "--alpha", str(a),
                       "--beta", str(b), "--frontend", "rbpf", "--backend", "eif", "--threads", "1",
                       "--progress=false", "--out", out] + (["--known_association"] if known else []) + args.extra
                jobs.append(cmd)
                cells.append((a, b, s, known, out))
    pool(args, jobs)
    print("| alpha | beta | duplicates / true landmarks seen | by the true ids | median final RMS est / known [m] | "
          "median online RMS est / known [m] | 10-sigma successes est / known | "
          "online 10-sigma successes est / known | wrong merges (sharing no true landmark) | merges / splits |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for a, b in settings:
        rows = {k: [report(o) for (aa, bb, s, kn, o) in cells if (aa, bb, kn) == (a, b, k)] for k in (False, True)}
        est, kn = rows[False], rows[True]
        dup = sum(r["metrics"]["map"]["duplicates"] for r in est)
        seen = sum(r["metrics"]["map"]["matched"] for r in est)
        by_id = sum(r["metrics"].get("map_by_truth_label", {}).get("duplicates", 0) for r in est)
        med = lambda rs, key: statistics.median(r["metrics"][key]["rms_position_m"] for r in rs)
        ok = lambda rs, key="trajectory": sum(not r["metrics"][key]["failed_10_sigma_test"] for r in rs)
        wrong = lambda key: sum(r["metrics"]["association_vs_truth_id"][key] for r in est)
        merges = sum(r["estimator_counters"].get("join_landmarks_merged", 0) for r in est)
        splits = sum(r["estimator_counters"].get("join_features_split", 0) for r in est)
        print(f"| {a} | {b} | {dup} / {seen} ({100.0 * dup / max(seen, 1):.1f} %) | {by_id} | "
              f"{med(est, 'trajectory'):.3f} / {med(kn, 'trajectory'):.3f} | "
              f"{med(est, 'trajectory_online'):.3f} / {med(kn, 'trajectory_online'):.3f} | "
              f"{ok(est)} / {ok(kn)} of {len(est)} | "
              f"{ok(est, 'trajectory_online')} / {ok(kn, 'trajectory_online')} of {len(est)} | "
              f"{wrong('wrong_merges')} ({wrong('wrong_merges_sharing_no_true_landmark')}) | {merges} / {splits} |")


def combined(args):
    jobs, maps = [], []
    for s in args.seeds:
        out = os.path.join(args.out, f"combined_s{s}")
        jobs.append([args.bin, "run", "--scenario", "combined-2km", "--seed", str(s), "--frontend", "rbpf",
                     "--backend", "eif", "--threads", "1", "--progress=false", "--out", out] + args.extra)
        maps.append((s, out))
    pool(args, jobs)
    variants = {"no revision": ["--join_merge=false", "--join_split=false"], "merges (default)": [],
                "merges and splits": ["--join_split=true"]}
    jobs, cells = [], []
    for s, out in maps:
        for name, flags in variants.items():
            j = out + "_join_" + name.replace(" ", "_")
            jobs.append([args.bin, "join", "--submaps", os.path.join(out, "submaps.jsonl"), "--backend", "eif",
                         "--scenario", "combined-2km", "--seed", str(s), "--out", j] + flags +
                        args.extra)
            cells.append((name, s, j))
    pool(args, jobs)
    print("| back-end association | duplicates (by the true ids) | wrong merges (sharing no true landmark) | 10-sigma failures | "
          "final anchor RMS median (max) [m] | merges / splits | join time median [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name in variants:
        rs = [report(j) for (n, s, j) in cells if n == name]
        m = [r["metrics"] for r in rs]
        rms = [x["anchors"]["rms_position_m"] for x in m]
        print(f"| {name} | {sum(x['map']['duplicates'] for x in m)} "
              f"({sum(x.get('map_by_truth_label', {}).get('duplicates', 0) for x in m)}) | "
              f"{sum(x['association_vs_truth_id']['wrong_merges'] for x in m)} "
              f"({sum(x['association_vs_truth_id']['wrong_merges_sharing_no_true_landmark'] for x in m)}) | "
              f"{sum(x['anchors']['failed_10_sigma_test'] for x in m)} of {len(m)} | "
              f"{statistics.median(rms):.2f} ({max(rms):.2f}) | "
              f"{sum(r['counts'].get('landmarks_merged', 0) for r in rs)} / "
              f"{sum(r['counts'].get('features_split', 0) for r in rs)} | "
              f"{statistics.median(r['time_seconds']['total'] for r in rs):.2f} |")


def backends(args):
    """Every joining back-end on the same recorded combined-2km RBPF local maps."""
    jobs, maps = [], []
    for s in args.seeds:
        out = os.path.join(args.out, f"combined_s{s}")
        jobs.append([args.bin, "run", "--scenario", "combined-2km", "--seed", str(s), "--frontend", "rbpf",
                     "--backend", "eif", "--threads", "1", "--progress=false", "--out", out])
        maps.append((s, out))
    pool(args, jobs)
    # The last: the EIF linearised once per join, as the dense EKF joiners are.
    names = ["eif", "ceres", "ekf", "tree-ekf", "tree-eif", "tree-ceres", "eif --single_linearization"]
    jobs, cells = [], {}
    for s, out in maps:
        for name in names:
            b, *flags = name.split()
            j = os.path.join(args.out, f"combined_s{s}_backend_{name.replace(' --', '_')}")
            jobs.append([args.bin, "join", "--submaps", os.path.join(out, "submaps.jsonl"), "--backend", b,
                         "--scenario", "combined-2km", "--seed", str(s), "--out", j] + flags +
                        args.extra)
            cells[(name, s)] = j
    pool(args, jobs)
    rms = lambda b, s: report(cells[(b, s)])["metrics"]["anchors"]["rms_position_m"]
    print("| back-end | final anchor RMS median (max) [m] | seeds above 1.5x the EIF's | loop re-observations "
          "merged / missed | duplicates | wrong merges (sharing no true landmark) | join time median [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for b in names:
        rs = [report(cells[(b, s)]) for s in args.seeds]
        v = [rms(b, s) for s in args.seeds]
        above = [s for s in args.seeds if rms(b, s) > 1.5 * rms("eif", s)]
        a = [r["metrics"]["association_vs_truth_id"] for r in rs]
        print(f"| `{b}` | {statistics.median(v):.2f} ({max(v):.2f}) | {len(above)} {above if above else ''} | "
              f"{sum(x['reobserved_loop_merged'] for x in a)} / {sum(x['reobserved_loop_missed'] for x in a)} | "
              f"{sum(r['metrics']['map']['duplicates'] for r in rs)} | {sum(x['wrong_merges'] for x in a)} "
              f"({sum(x['wrong_merges_sharing_no_true_landmark'] for x in a)}) | "
              f"{statistics.median(r['time_seconds']['total'] for r in rs):.2f} |")


def victoria(args):
    data = os.environ.get("SUBSLAM_VICTORIA_PARK", os.path.join(ROOT, "..", "shared", "data", "victoria_park"))
    # The particle filter's seed and threads only where there is one (the tool refuses a flag
    # the chosen front-end does not read).
    variants = {"rbpf+eif": ["--frontend", "rbpf", "--backend", "eif", "--threads", "1"],
                "ekfslam": ["--frontend", "ekfslam"]}
    jobs, cells = [], []
    for yaw in ("", "-0.0182"):
        for name, flags in variants.items():
            for s in (args.seeds if name != "ekfslam" else args.seeds[:1]):
                out = os.path.join(args.out, f"vp_{name}_yaw{yaw or 'none'}_s{s}")
                seed = ["--filter_seed", str(s)] if name != "ekfslam" else []
                cmd = [args.bin, "run", "--dataset", data, *seed, "--progress=false", "--out", out] + flags + (["--sensor_yaw", yaw] if yaw else []) + args.extra
                jobs.append(cmd)
                cells.append((yaw, name, s, out))
    pool(args, jobs)
    print("| sensor yaw | estimator | aligned RMS vs GPS median (range) [m] | gross GPS faults dropped | "
          "estimator time median [s] | runs |")
    print("| --- | --- | --- | --- | --- | --- |")
    for yaw in ("", "-0.0182"):
        for name in variants:
            rs = [report(o) for (y, n, s, o) in cells if (y, n) == (yaw, name)]
            v = [r["metrics"]["gps_final"]["aligned_rms_m"] for r in rs]
            t = [r["time_seconds"]["total"] for r in rs]
            print(f"| {yaw or 'none'} | {name} | {statistics.median(v):.2f} ({min(v):.2f}-{max(v):.2f}) | "
                  f"{rs[0]['metrics']['gps_final']['rejected_fixes']} | {statistics.median(t):.2f} | {len(v)} |")


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", choices=["hybrid", "combined", "victoria", "backends"])
    p.add_argument("--seeds", type=seeds)
    p.add_argument("--bin", default=os.path.join(ROOT, "build", "apps", "subslam"))
    p.add_argument("--out", default="/tmp/subslam_sweep")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--reuse", action="store_true", help="keep the outputs of runs already in --out")
    args = p.parse_args(argv)
    args.extra = extra
    args.seeds = args.seeds or seeds({"hybrid": "1-20", "combined": "1-20", "victoria": "1-8", "backends": "1-20"}[args.sweep])
    os.makedirs(args.out, exist_ok=True)
    {"hybrid": hybrid, "combined": combined, "victoria": victoria, "backends": backends}[args.sweep](args)


if __name__ == "__main__":
    main()
