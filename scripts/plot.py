#!/usr/bin/python3
"""Figures of a subslam output directory, drawn with matplotlib (Debian's python3-matplotlib).

  scripts/plot.py DIR [DIR ...] [--formats png,svg]     (or: subslam plot DIR ...)

DIR is what `subslam run`, `subslam join`, `subslam solve` or `subslam study` wrote (docs/formats.md); the
figures go into DIR/plots/, each as PNG and SVG:

  run    map          the map with 95 % ellipses over the true landmarks, the estimated
                      (online and final) against the true trajectory, or the GPS track
         nees         pose NEES over time, online and final, with the single-run 95 % χ²₃ band
         errors       position error over time, online and final
         joins        time per join (local-map front-ends with a back-end)
  join   map, joins   the anchors and the map, as for a run; time per join
  solve  solutions    each method's solution (poses and points from METHOD.g2o), one panel
                      per method; errors: each method's final error (½ Σ rᵀΩr, log scale)
                      and time
  study  hybridslam:  success rate per method and setting with 95 % intervals and the paper's
                      figures (success)
         others:      ANEES against time with the χ² band for the number of runs (anees),
                      mean consistency index (consistency), RMS position error (rms)
         every study: median run time per method (timings); cumulative joining time against
                      the local maps joined, per method (join_times)

Every landmark ellipse, curve and bar carries an SVG id (e.g. landmark-ellipse-7,
anees-rbpf-eif, solution-poses-lm), so that a figure's content can be checked, not only its existence.
"""
import argparse
import csv
import json
import math
import os
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402

# χ² quantiles (tables of the χ² distribution): the two-sided 95 % interval of one 3-dof
# NEES, and the 95 % contour of a 2-dof Gaussian.
CHI2_3DOF_025 = 0.2158
CHI2_3DOF_975 = 9.3484
CHI2_2DOF_95 = 5.9915


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return rows


def number(text):
    return float("nan") if text in ("nan", "-nan") else float(text)


def column(rows, name):
    return [number(r[name]) for r in rows]


def save(fig, out_dir, name, formats):
    os.makedirs(out_dir, exist_ok=True)
    written = []
    for fmt in formats:
        path = os.path.join(out_dir, f"{name}.{fmt}")
        fig.savefig(path, dpi=130, bbox_inches="tight")
        written.append(path)
    plt.close(fig)
    return written


def ellipse(x, y, cxx, cxy, cyy, **kw):
    """The 95 % ellipse of a 2-D Gaussian."""
    trace, det = cxx + cyy, cxx * cyy - cxy * cxy
    disc = math.sqrt(max(trace * trace / 4 - det, 0.0))
    l1, l2 = trace / 2 + disc, max(trace / 2 - disc, 0.0)
    angle = 0.5 * math.degrees(math.atan2(2 * cxy, cxx - cyy))
    s = math.sqrt(CHI2_2DOF_95)
    return Ellipse((x, y), 2 * s * math.sqrt(l1), 2 * s * math.sqrt(l2), angle=angle, **kw)


def draw_map(ax, d, trajectories):
    truth_landmarks = os.path.join(d, "truth_landmarks.csv")
    if os.path.exists(truth_landmarks):
        rows = read_csv(truth_landmarks)
        pts = ax.scatter(column(rows, "x"), column(rows, "y"), marker="x", color="black", s=18, zorder=3,
                         label=f"true landmarks ({len(rows)})")
        pts.set_gid("truth-landmarks")
    truth = os.path.join(d, "truth_trajectory.csv")
    if os.path.exists(truth):
        rows = read_csv(truth)
        (line,) = ax.plot(column(rows, "x"), column(rows, "y"), color="black", lw=1.0, label="true trajectory")
        line.set_gid("truth-trajectory")
    gps = os.path.join(d, "gps_aligned.csv")
    if os.path.exists(gps):
        rows = read_csv(gps)
        good = [r for r in rows if r["rejected"] == "0"]
        bad = [r for r in rows if r["rejected"] != "0"]
        ax.scatter(column(good, "x"), column(good, "y"), s=2, color="0.5", label=f"GPS, aligned ({len(good)})",
                   zorder=1).set_gid("gps")
        if bad:
            ax.scatter(column(bad, "x"), column(bad, "y"), s=20, color="red", marker="s",
                       label=f"GPS faults dropped ({len(bad)})", zorder=2).set_gid("gps-rejected")
    for name, label, style in trajectories:
        path = os.path.join(d, name)
        if not os.path.exists(path):
            continue
        rows = read_csv(path)
        (line,) = ax.plot(column(rows, "x"), column(rows, "y"), lw=1.0, label=label, **style)
        line.set_gid(name.replace(".csv", ""))
    rows = read_csv(os.path.join(d, "landmarks.csv"))
    for r in rows:
        e = ellipse(number(r["x"]), number(r["y"]), number(r["cov_xx"]), number(r["cov_xy"]), number(r["cov_yy"]),
                    fill=False, edgecolor="tab:blue", lw=0.8, zorder=4)
        e.set_gid(f"landmark-ellipse-{r['id']}")
        ax.add_patch(e)
    ax.scatter(column(rows, "x"), column(rows, "y"), s=6, color="tab:blue", zorder=4,
               label=f"estimated landmarks ({len(rows)}), 95 % ellipses").set_gid("landmarks")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize=7)


def draw_joins(d, out, formats, title):
    path = os.path.join(d, "joins.csv")
    if not os.path.exists(path):
        return []
    rows = read_csv(path)
    if not rows:
        return []
    fig, ax = plt.subplots(figsize=(7, 3.5))
    (line,) = ax.plot(column(rows, "map_id"), [1e3 * s for s in column(rows, "seconds")], lw=0.8)
    line.set_gid("join-seconds")
    ax.set_xlabel("local map")
    ax.set_ylabel("join time [ms]")
    ax.set_title(title, fontsize=9)
    ax.grid(True, lw=0.3)
    return save(fig, out, "joins", formats)


def plot_run(d, out, formats):
    report = json.load(open(os.path.join(d, "report.json")))
    title = f"{report.get('source', d)}: {report['configuration'].get('frontend', '')}"
    written = []
    fig, ax = plt.subplots(figsize=(8, 8))
    draw_map(ax, d, [("trajectory_online.csv", "online estimate", {"color": "tab:orange", "alpha": 0.7}),
                     ("trajectory_final.csv", "final estimate", {"color": "tab:green"})])
    ax.set_title(title, fontsize=9)
    written += save(fig, out, "map", formats)

    errors = os.path.join(d, "pose_errors.csv")
    if os.path.exists(errors):
        rows = read_csv(errors)
        t = column(rows, "t")
        for name, field, ylabel in (("nees", "nees", "pose NEES"), ("errors", "position_error_m", "position error [m]")):
            fig, ax = plt.subplots(figsize=(8, 3.5))
            for kind, color in (("online", "tab:orange"), ("final", "tab:green")):
                (line,) = ax.plot(t, column(rows, f"{kind}_{field}"), lw=0.7, color=color, label=f"{kind}")
                line.set_gid(f"{name}-{kind}")
            if name == "nees":
                band = ax.axhspan(CHI2_3DOF_025, CHI2_3DOF_975, color="0.85", zorder=0, label="95 % χ²₃ band")
                band.set_gid("nees-band")
                ax.set_yscale("log")
            ax.set_xlabel("t [s]")
            ax.set_ylabel(ylabel)
            ax.set_title(title, fontsize=9)
            ax.grid(True, lw=0.3)
            ax.legend(fontsize=7)
            written += save(fig, out, name, formats)
    written += draw_joins(d, out, formats, title)
    return written


def plot_join(d, out, formats):
    report = json.load(open(os.path.join(d, "report.json")))
    title = f"subslam join: {report['configuration'].get('backend', '')}"
    fig, ax = plt.subplots(figsize=(8, 8))
    draw_map(ax, d, [("anchors.csv", "anchors (start of each local map)", {"color": "tab:green", "marker": ".",
                                                                          "ms": 3})])
    ax.set_title(title, fontsize=9)
    return save(fig, out, "map", formats) + draw_joins(d, out, formats, title)


def read_g2o(path):
    """The vertices of a g2o file: pose (x, y) and point (x, y) lists."""
    poses, points = [], []
    with open(path) as f:
        for line in f:
            fields = line.split()
            if fields and fields[0] == "VERTEX_SE2":
                poses.append((float(fields[2]), float(fields[3])))
            elif fields and fields[0] == "VERTEX_XY":
                points.append((float(fields[2]), float(fields[3])))
    return poses, points


def plot_solve(d, out, formats):
    report = json.load(open(os.path.join(d, "report.json")))
    methods = [m for m in report["methods"] if m["status"] == "ok"]
    if not methods:
        raise SystemExit(f"{d}: no method solved the graph")
    graph = report.get("graph", {}).get("file", "")
    columns = min(3, len(methods))
    rows_ = (len(methods) + columns - 1) // columns
    fig, axes = plt.subplots(rows_, columns, figsize=(4.2 * columns, 4.2 * rows_), squeeze=False)
    for k, m in enumerate(methods):
        ax = axes[k // columns][k % columns]
        poses, points = read_g2o(os.path.join(d, f"{m['name']}.g2o"))
        (line,) = ax.plot([p[0] for p in poses], [p[1] for p in poses], lw=0.5, color="tab:blue")
        line.set_gid(f"solution-poses-{m['name']}")
        if points:
            dots = ax.scatter([p[0] for p in points], [p[1] for p in points], s=6, color="tab:red")
            dots.set_gid(f"solution-points-{m['name']}")
        ax.set_title(f"{m['name']}: error {m['error']:.6g}, {m['seconds']:.3g} s", fontsize=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=6)
    for k in range(len(methods), rows_ * columns):
        axes[k // columns][k % columns].axis("off")
    fig.suptitle(f"subslam solve: {graph}", fontsize=9)
    written = save(fig, out, "solutions", formats)
    fig, (ax_error, ax_time) = plt.subplots(1, 2, figsize=(9, 3.5))
    for k, m in enumerate(methods):
        bar = ax_error.bar(k, m["error"], color=f"C{k}")
        bar.patches[0].set_gid(f"error-{m['name']}")
        bar = ax_time.bar(k, m["seconds"], color=f"C{k}")
        bar.patches[0].set_gid(f"seconds-{m['name']}")
    for ax, label in ((ax_error, "final error ½Σ rᵀΩr"), (ax_time, "time [s]")):
        ax.set_xticks(range(len(methods)))
        ax.set_xticklabels([m["name"] for m in methods], fontsize=7, rotation=30)
        ax.set_yscale("log")
        ax.set_ylabel(label, fontsize=8)
        ax.grid(True, axis="y", lw=0.3)
    fig.suptitle(f"subslam solve: {graph} (start: error {report['initial_error']:.6g})", fontsize=9)
    return written + save(fig, out, "errors", formats)


def setting_label(row, names):
    return ", ".join(f"{n} {row[n]:g}" for n in names)


def plot_hybridslam(summary, out, formats):
    rows = summary["rows"]
    settings = []
    for r in rows:
        if (r["alpha"], r["beta"]) not in settings:
            settings.append((r["alpha"], r["beta"]))
    methods = []
    for r in rows:
        if r["method"] not in methods:
            methods.append(r["method"])
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(methods)
    for m, method in enumerate(methods):
        for s, (alpha, beta) in enumerate(settings):
            row = next((r for r in rows if r["method"] == method and (r["alpha"], r["beta"]) == (alpha, beta)), None)
            if row is None:
                continue
            x = s + (m - (len(methods) - 1) / 2) * width
            rate = 100 * row["success_rate"]
            lo, hi = (100 * v for v in row["success_rate_ci95"])
            bar = ax.bar(x, rate, width, color=f"C{m}", label=method if s == 0 else None)
            bar.patches[0].set_gid(f"success-{method}-{s}")
            ax.errorbar(x, rate, yerr=[[rate - lo], [hi - rate]], color="black", capsize=2, lw=0.8)
            if row["paper_success_rate"] is not None:
                ax.plot(x, 100 * row["paper_success_rate"], marker="_", ms=14, mew=2.5, color="red",
                        label="the paper" if (m, s) == (1, 0) else None)
    ax.set_xticks(range(len(settings)))
    ax.set_xticklabels([f"α {a:.1f}, β {b:.2f}" for a, b in settings])
    ax.set_ylabel("success rate [%] (95 % interval)")
    ax.set_ylim(0, 105)
    ax.set_title(f"{summary['title']}\n{rows[0]['trials']} trials per bar", fontsize=8)
    ax.legend(fontsize=7, ncol=6, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    ax.grid(True, axis="y", lw=0.3)
    return save(fig, out, "success", formats)


def plot_monte_carlo(summary, setting_names, out, formats):
    rows = [r for r in summary["rows"] if "curve" in r]  # not the runs on a real data set
    groups = []
    for r in rows:
        key = tuple(r[n] for n in setting_names)
        if key not in groups:
            groups.append(key)
    written = []
    for key in groups:
        suffix = "".join(f"-{n}{v:g}" for n, v in zip(setting_names, key))
        group = [r for r in rows if tuple(r[n] for n in setting_names) == key]
        label = setting_label(group[0], setting_names)
        for name, field, ylabel, log in (("anees", "anees", "pose ANEES (3 dof)", True),
                                         ("consistency", "mean_ci", "mean consistency index", True),
                                         ("rms", "rms_position_m", "RMS position error [m]", False)):
            fig, ax = plt.subplots(figsize=(9, 4))
            for m, r in enumerate(group):
                c = r["curve"]
                (line,) = ax.plot(c["t_s"], c[field], color=f"C{m}", lw=1.0, label=r["method"])
                line.set_gid(f"{name}-{r['method']}")
            if name == "anees":
                c = group[0]["curve"]
                band = ax.fill_between(c["t_s"], c["band_low"], c["band_high"], color="0.8", zorder=0,
                                       label=f"95 % χ² band, {group[0]['trials']} runs")
                band.set_gid("anees-band")
            if name == "consistency":
                ax.axhline(1.0, color="black", lw=0.8, ls="--", label="CI = 1")
            if log:
                ax.set_yscale("log")
                # A diverged filter's NEES reaches 1e30; clip so the consistent ones stay readable.
                cap = 1e3 * (max(group[0]["curve"]["band_high"]) if name == "anees" else 1.0)
                if max(max(r["curve"][field], default=0.0) for r in group) > cap:
                    ax.set_ylim(top=cap)
                    ax.text(0.99, 0.98, f"clipped at {cap:.3g}", transform=ax.transAxes, ha="right", va="top",
                            fontsize=7)
            ax.set_xlabel("t [s]")
            ax.set_ylabel(ylabel)
            ax.set_title(f"{summary['title']}" + (f"\n{label}" if label else ""), fontsize=8)
            ax.grid(True, lw=0.3)
            ax.legend(fontsize=7, ncol=2)
            written += save(fig, out, f"{name}{suffix}", formats)
    return written


def plot_timings(d, out, formats, title):
    runs = {r["run"]: r["method"] for r in read_csv(os.path.join(d, "runs.csv"))}
    by_method = {}
    for r in read_csv(os.path.join(d, "timings.csv")):
        by_method.setdefault(runs[r["run"]], []).append(number(r["wall_s"]))
    if not by_method:
        return []
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for m, (method, values) in enumerate(by_method.items()):
        bar = ax.bar(m, statistics.median(values), color=f"C{m}")
        bar.patches[0].set_gid(f"timing-{method}")
    ax.set_xticks(range(len(by_method)))
    ax.set_xticklabels(list(by_method), fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("median wall time per run [s]")
    ax.set_title(title, fontsize=8)
    ax.grid(True, axis="y", lw=0.3)
    return save(fig, out, "timings", formats)


def plot_join_times(d, out, formats, title, setting_names):
    """Cumulative joining time against the local maps joined, median over each group's runs (up to the
    number of maps every run of the group has)."""
    path = os.path.join(d, "join_times.csv")
    if not os.path.exists(path):
        return []
    runs = {r["run"]: r for r in read_csv(os.path.join(d, "runs.csv"))}
    cumulative = {}  # run -> [cumulative seconds after join j]
    for r in read_csv(path):
        c = cumulative.setdefault(r["run"], [])
        c.append((c[-1] if c else 0.0) + number(r["seconds"]))
    groups = {}
    for run, c in cumulative.items():
        row = runs[run]
        key = row["method"] + "".join(f" {n} {row[n]}" for n in setting_names if row.get(n, "nan") != "nan")
        groups.setdefault(key, []).append(c)
    fig, ax = plt.subplots(figsize=(8, 4))
    for g, (key, curves) in enumerate(groups.items()):
        length = min(len(c) for c in curves)  # the joins every run of the group made
        median = [statistics.median(c[j] for c in curves) for j in range(length)]
        (line,) = ax.plot(range(1, length + 1), median, color=f"C{g}", lw=1.0, label=key)
        line.set_gid("join-time-" + key.replace(" ", "-"))
    ax.set_yscale("log")
    ax.set_xlabel("local maps joined")
    ax.set_ylabel("joining time so far [s] (median over runs)")
    ax.set_title(title, fontsize=8)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7)
    return save(fig, out, "join_times", formats)


def plot_study(d, out, formats):
    config = json.load(open(os.path.join(d, "config.json")))
    summary_path = os.path.join(d, "summary.json")
    if not os.path.exists(summary_path):
        raise SystemExit(f"{d}: no summary.json (a slice? merge the slices with `subslam study merge` first)")
    summary = json.load(open(summary_path))
    settings = list(config["configuration"].get("settings", {}))
    if config["study"] == "hybridslam":
        written = plot_hybridslam(summary, out, formats)
    else:
        written = plot_monte_carlo(summary, settings, out, formats)
    return (written + plot_timings(d, out, formats, f"{config['study']}: run times") +
            plot_join_times(d, out, formats, f"{config['study']}: joining time", settings))


def plot(d, formats):
    out = os.path.join(d, "plots")
    if os.path.exists(os.path.join(d, "config.json")) and os.path.exists(os.path.join(d, "runs.csv")):
        return plot_study(d, out, formats)
    if os.path.exists(os.path.join(d, "trajectory_online.csv")):
        return plot_run(d, out, formats)
    if os.path.exists(os.path.join(d, "anchors.csv")):
        return plot_join(d, out, formats)
    report = os.path.join(d, "report.json")
    if os.path.exists(report) and json.load(open(report)).get("job") == "solve":
        return plot_solve(d, out, formats)
    raise SystemExit(f"{d}: not an output directory of subslam run, join, solve or study")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dirs", nargs="+", help="output directories of subslam run, join, solve or study")
    parser.add_argument("--formats", default="png,svg", help="comma-separated (default png,svg)")
    args = parser.parse_args()
    for d in args.dirs:
        for path in plot(d, args.formats.split(",")):
            print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
