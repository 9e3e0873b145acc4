#!/usr/bin/python3
"""Figures of a subslam output directory, drawn with matplotlib (Debian's python3-matplotlib).

  scripts/plot.py DIR [DIR ...] [--formats png,svg]     (or: subslam plot DIR ...)

DIR is what `subslam run`, `subslam join`, `subslam solve` or `subslam study` wrote (docs/formats.md); the
figures go into DIR/plots/, each as PNG and SVG:

  run    map          the map with 95 % ellipses over the true landmarks, the estimated
                      (online and final) against the true trajectory, or the GPS track
         nees         pose NEES over time, online and final, with the single-run 95 % χ²₃ band
                      (data sets with true poses)
         errors       position error over time, online and final (data sets with true poses)
         gps_errors   distance from the estimate to each GPS fix over time, online and final,
                      each in its gps_online / gps_final alignment (data sets with GPS)
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
Log axes carry plain tick labels (0.2, 5, 300).
"""
import argparse
import csv
import functools
import json
import math
import os
import statistics
import sys
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

# χ² quantiles (tables of the χ² distribution): the two-sided 95 % interval of one 3-dof
# NEES, and the 95 % contour of a 2-dof Gaussian.
CHI2_3DOF_025 = 0.2158
CHI2_3DOF_975 = 9.3484
CHI2_2DOF_95 = 5.9915

DPI = 130
# Drawing order of the map, bottom to top: the ellipses above every point, so that an ellipse
# smaller than a landmark's mark still shows on it.
Z_GPS, Z_TRAJECTORY, Z_TRUE_LANDMARKS, Z_LANDMARKS, Z_ELLIPSES = 1, 2, 3, 4, 5
ELLIPSE_COLOR = "#d62728"  # red: no other element of the map uses it


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return rows


@functools.lru_cache(maxsize=None)
def read_table(path):
    """A numeric CSV file (trajectories, errors, GPS, landmarks) as {column: numpy array}, read
    once per process however many figures use it."""
    with open(path) as f:
        names = f.readline().strip().split(",")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a file of a header only: no rows
        values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if values.size == 0:
        values = np.zeros((0, len(names)))
    return {name: values[:, k] for k, name in enumerate(names)}


def number(text):
    return float("nan") if text in ("nan", "-nan") else float(text)


def save(fig, out_dir, name, formats):
    """Writes the figure in each format. The tight bounding box is measured once, with the first
    format's renderer, and reused, instead of a layout pass per format."""
    os.makedirs(out_dir, exist_ok=True)
    written, bbox = [], "tight"
    for fmt in formats:
        path = os.path.join(out_dir, f"{name}.{fmt}")
        fig.savefig(path, dpi=DPI, bbox_inches=bbox)
        if bbox == "tight":
            bbox = fig.get_tightbbox(fig.canvas.get_renderer()).padded(plt.rcParams["savefig.pad_inches"])
        written.append(path)
    plt.close(fig)
    return written


def plain_number(value):
    """A tick value as 0.2, 5 or 300 (1e-05 → 1e-5 and 1e+30 → 1e30 beyond six digits)."""
    text = f"{value:.6g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


def plain_log_scale(ax, axis="y"):
    """A log scale whose tick labels are plain numbers (2, 0.5, 300) instead of matplotlib's
    mathtext (2×10⁰, 10⁻¹). Minor ticks are labelled, as by the default log formatter, only on
    an axis spanning one decade or less: those at 2, 3 and 5 × 10ᵏ down to 0.4 decade, all of
    them below, so that labels do not crowd."""
    getattr(ax, f"set_{axis}scale")("log")
    ticks = ax.yaxis if axis == "y" else ax.xaxis

    def minor(value, _):
        low, high = sorted(ticks.get_view_interval())
        decades = math.log10(high / low) if low > 0 else math.inf
        mantissa = round(value / 10 ** math.floor(math.log10(value)), 6) if value > 0 else 0.0
        if decades > 1 or (decades > 0.4 and mantissa not in (2.0, 3.0, 5.0)):
            return ""
        return plain_number(value)

    ticks.set_major_formatter(FuncFormatter(lambda value, _: plain_number(value)))
    ticks.set_minor_formatter(FuncFormatter(minor))


def log_bar_limits(ax, values):
    """Limits of a log-scale bar chart from a third of the smallest bar to three times the
    largest: bars of nearly equal heights (two solvers' errors equal to 12 digits) would
    otherwise get an axis spanning a 10⁻¹² ratio, which matplotlib cannot tick."""
    positive = [v for v in values if v > 0 and math.isfinite(v)]
    if positive:
        ax.set_ylim(min(positive) / 3, max(positive) * 3)


def ellipse(x, y, cxx, cxy, cyy, **kw):
    """The 95 % ellipse of a 2-D Gaussian."""
    trace, det = cxx + cyy, cxx * cyy - cxy * cxy
    disc = math.sqrt(max(trace * trace / 4 - det, 0.0))
    l1, l2 = trace / 2 + disc, max(trace / 2 - disc, 0.0)
    angle = 0.5 * math.degrees(math.atan2(2 * cxy, cxx - cyy))
    s = math.sqrt(CHI2_2DOF_95)
    return Ellipse((x, y), 2 * s * math.sqrt(l1), 2 * s * math.sqrt(l2), angle=angle, **kw)


def ellipse_axes(cxx, cxy, cyy):
    """The full major and minor axes [m] of the 95 % ellipses of the covariances (arrays)."""
    trace, det = cxx + cyy, cxx * cyy - cxy * cxy
    disc = np.sqrt(np.maximum(trace * trace / 4 - det, 0.0))
    s = 2 * math.sqrt(CHI2_2DOF_95)
    return s * np.sqrt(trace / 2 + disc), s * np.sqrt(np.maximum(trace / 2 - disc, 0.0))


def points_per_metre(ax):
    """The map's scale in points per metre, once its limits and equal aspect are settled."""
    ax.apply_aspect()
    width_pt = ax.get_position().width * ax.figure.get_figwidth() * 72
    low, high = ax.get_xlim()
    return width_pt / (high - low) if high > low else 1.0


def draw_map(ax, d, trajectories):
    """The map: the true landmarks (black ×) or the aligned GPS fixes (grey), the trajectories,
    and the estimated landmarks (blue dots) under their 95 % ellipses (red, on top of every
    point). The dots are kept smaller than the typical ellipse on the page, down to 1.5 pt, and
    the legend gives the ellipses' median size, which a map kilometres across cannot show."""
    truth_landmarks = os.path.join(d, "truth_landmarks.csv")
    if os.path.exists(truth_landmarks):
        t = read_table(truth_landmarks)
        pts = ax.scatter(t["x"], t["y"], marker="x", color="black", s=14, lw=0.8, zorder=Z_TRUE_LANDMARKS,
                         label=f"true landmarks ({len(t['x'])})")
        pts.set_gid("truth-landmarks")
    truth = os.path.join(d, "truth_trajectory.csv")
    if os.path.exists(truth):
        t = read_table(truth)
        (line,) = ax.plot(t["x"], t["y"], color="black", lw=1.0, zorder=Z_TRAJECTORY, label="true trajectory")
        line.set_gid("truth-trajectory")
    gps = os.path.join(d, "gps_aligned.csv")
    if os.path.exists(gps):
        t = read_table(gps)
        good, bad = t["rejected"] == 0, t["rejected"] != 0
        ax.scatter(t["x"][good], t["y"][good], s=2, color="0.5", label=f"GPS, aligned ({good.sum()})",
                   zorder=Z_GPS).set_gid("gps")
        if bad.any():
            ax.scatter(t["x"][bad], t["y"][bad], s=20, color="magenta", marker="s",
                       label=f"GPS faults dropped ({bad.sum()})", zorder=Z_GPS).set_gid("gps-rejected")
    for name, label, style in trajectories:
        path = os.path.join(d, name)
        if os.path.exists(path):
            t = read_table(path)
            (line,) = ax.plot(t["x"], t["y"], lw=1.0, zorder=Z_TRAJECTORY, label=label, **style)
            line.set_gid(name.replace(".csv", ""))
    lm = read_table(os.path.join(d, "landmarks.csv"))
    major, minor = ellipse_axes(lm["cov_xx"], lm["cov_xy"], lm["cov_yy"])
    # The limits hold each ellipse's axis-aligned bounding box.
    half_x, half_y = (math.sqrt(CHI2_2DOF_95) * np.sqrt(lm[c]) for c in ("cov_xx", "cov_yy"))
    corners = np.concatenate([np.column_stack([lm["x"] - half_x, lm["y"] - half_y]),
                              np.column_stack([lm["x"] + half_x, lm["y"] + half_y])])
    ax.update_datalim(corners[np.isfinite(corners).all(axis=1)])
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    scale = points_per_metre(ax)
    median_major, median_minor = (float(np.median(a)) if len(a) else 0.0 for a in (major, minor))
    dot_pt = min(max(0.6 * median_minor * scale, 1.5), 3.0)
    ax.scatter(lm["x"], lm["y"], s=dot_pt ** 2, color="tab:blue", lw=0, zorder=Z_LANDMARKS,
               label=f"estimated landmarks ({len(lm['x'])})").set_gid("landmarks")
    # Large ellipses overlap: thinner rings, and translucent ones where together they would cover
    # the map more than twice over (3,000 local-map features 50 m across), so that the
    # trajectories and points beneath still show.
    lw = 0.9 if median_major * scale < 15 else 0.5
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    coverage = float(np.sum(math.pi / 4 * major * minor)) / max((x1 - x0) * (y1 - y0), 1e-300)
    alpha = min(1.0, max(0.15, 2.0 / coverage)) if coverage > 0 else 1.0
    for k, landmark_id in enumerate(lm["id"]):
        e = ellipse(lm["x"][k], lm["y"][k], lm["cov_xx"][k], lm["cov_xy"][k], lm["cov_yy"][k], fill=False,
                    edgecolor=ELLIPSE_COLOR, lw=lw, alpha=alpha, zorder=Z_ELLIPSES)
        e.set_gid(f"landmark-ellipse-{int(landmark_id)}")
        if k == 0:
            e.set_label(f"95 % ellipses (median {median_major:.3g} × {median_minor:.3g} m)")
        ax.add_artist(e)  # not add_patch, which would measure each ellipse's path for the limits again
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.3)
    # Below the axes, not over the map; loc="best" would also cost a search over every point.
    legend = ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=3, fontsize=7)
    for patch in legend.get_patches():
        patch.set_alpha(1.0)  # the ellipses' key opaque, however translucent the ellipses


def draw_joins(d, out, formats, title):
    path = os.path.join(d, "joins.csv")
    if not os.path.exists(path):
        return []
    rows = read_table(path)
    if not len(rows["map_id"]):
        return []
    fig, ax = plt.subplots(figsize=(7, 3.5))
    (line,) = ax.plot(rows["map_id"], 1e3 * rows["seconds"], lw=0.8)
    line.set_gid("join-seconds")
    ax.set_xlabel("local map")
    ax.set_ylabel("join time [ms]")
    ax.set_title(title, fontsize=9)
    ax.grid(True, lw=0.3)
    return save(fig, out, "joins", formats)


def time_axes(ax, ylabel, title):
    """Labels, grid and legend of a figure over time; the legend right of the axes, over no
    curve (loc="best" would search every point of curves 70,000 steps long)."""
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def plot_pose_errors(d, out, formats, title):
    """Against true poses (pose_errors.csv): the pose NEES with the single-run 95 % χ²₃ band,
    and the position error, online and final."""
    path = os.path.join(d, "pose_errors.csv")
    if not os.path.exists(path):
        return []
    e = read_table(path)
    written = []
    for name, field, ylabel in (("nees", "nees", "pose NEES"), ("errors", "position_error_m", "position error [m]")):
        fig, ax = plt.subplots(figsize=(8, 3.5))
        if name == "nees":
            band = ax.axhspan(CHI2_3DOF_025, CHI2_3DOF_975, color="0.85", zorder=0, label="95 % χ²₃ band")
            band.set_gid("nees-band")
            plain_log_scale(ax)
        for kind, color in (("online", "tab:orange"), ("final", "tab:green")):
            (line,) = ax.plot(e["t"], e[f"{kind}_{field}"], lw=0.7, color=color, label=kind)
            line.set_gid(f"{name}-{kind}")
        time_axes(ax, ylabel, title)
        written += save(fig, out, name, formats)
    return written


def rigid(pose, x, y):
    """The points (x, y) moved by the 2-D pose (tx, ty, θ)."""
    tx, ty, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    return tx + c * x - s * y, ty + s * x + c * y


def gps_distances(d, report):
    """Per GPS fix the gps_online / gps_final metrics compare (report.json; eval/gps_alignment.h):
    inside the trajectory's time span and not a gross fault. Returns {"online" | "final": (the
    fixes' times, the distance [m] from the trajectory, interpolated at each fix's time, to the
    fix in that metric's alignment)}, whose RMS is the metric's `aligned_rms_m`, and the times
    of the gross faults.

    gps_aligned.csv holds the fixes in the final trajectory's frame (gps_final's transform
    undone); the online trajectory is moved into that frame by gps_online's transform followed
    by gps_final's inverse, which gives each fix its distance in gps_online's alignment."""
    gps = read_table(os.path.join(d, "gps_aligned.csv"))
    metrics = report.get("metrics", {})
    final_t = metrics["gps_final"]["gps_T_estimate"]
    distances = {}
    for kind, name in (("online", "trajectory_online.csv"), ("final", "trajectory_final.csv")):
        metric = metrics.get(f"gps_{kind}")
        path = os.path.join(d, name)
        if metric is None or not os.path.exists(path):
            continue
        traj = read_table(path)
        if len(traj["t"]) < 2:
            continue
        used = (gps["rejected"] == 0) & (gps["t"] >= traj["t"][0]) & (gps["t"] <= traj["t"][-1])
        t = gps["t"][used]
        x, y = np.interp(t, traj["t"], traj["x"]), np.interp(t, traj["t"], traj["y"])
        if kind == "online":
            # T_final⁻¹ · T_online: rotate and translate by T_online, then undo T_final.
            gx, gy = rigid(metric["gps_T_estimate"], x, y)
            x, y = rigid((0.0, 0.0, -final_t[2]), gx - final_t[0], gy - final_t[1])
        distances[kind] = (t, np.hypot(x - gps["x"][used], y - gps["y"][used]))
    return distances, gps["t"][gps["rejected"] != 0]


def break_gaps(t, values, factor=5.0):
    """t and values with a NaN inserted into every gap longer than `factor` median intervals,
    so that a curve is not drawn across times without data (GPS outages)."""
    if len(t) < 3:
        return t, values
    dt = np.diff(t)
    gaps = np.nonzero(dt > factor * np.median(dt))[0] + 1
    return np.insert(t, gaps, np.nan), np.insert(values, gaps, np.nan)


def plot_gps_errors(d, out, formats, title, report):
    """The distance from the estimate to each GPS fix over time, online and final, each in its
    metric's alignment (gps_distances), not joined across GPS outages (a fix between two of them
    is a dot); the gross GPS faults dropped as dashed grey lines at their times."""
    if not os.path.exists(os.path.join(d, "gps_aligned.csv")) or "gps_final" not in report.get("metrics", {}):
        return []
    distances, faults = gps_distances(d, report)
    if not distances:
        return []
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for kind, color in (("online", "tab:orange"), ("final", "tab:green")):
        if kind in distances:
            t, distance = distances[kind]
            rms = math.sqrt(np.mean(distance ** 2))
            t_drawn, drawn = break_gaps(t, distance)
            (line,) = ax.plot(t_drawn, drawn, lw=0.7, color=color, label=f"{kind} (RMS {rms:.3g} m)")
            line.set_gid(f"gps-error-{kind}")
            # A fix between two outages makes no line: a dot.
            padded = np.concatenate(([np.nan], drawn, [np.nan]))
            alone = np.isfinite(drawn) & np.isnan(padded[:-2]) & np.isnan(padded[2:])
            if alone.any():
                (dots,) = ax.plot(t_drawn[alone], drawn[alone], ls="none", marker=".", ms=3, color=color)
                dots.set_gid(f"gps-error-{kind}-alone")
    for k, fault_t in enumerate(faults):
        ax.axvline(fault_t, color="0.5", lw=0.8, ls="--", zorder=0,
                   label=f"GPS faults dropped ({len(faults)})" if k == 0 else None).set_gid(f"gps-fault-{k}")
    time_axes(ax, "distance to GPS fix [m]", title)
    ax.set_ylim(bottom=0)
    return save(fig, out, "gps_errors", formats)


def plot_run(d, out, formats):
    report = json.load(open(os.path.join(d, "report.json")))
    title = f"{report.get('source', d)}: {report['configuration'].get('frontend', '')}"
    written = []
    fig, ax = plt.subplots(figsize=(8, 8))
    draw_map(ax, d, [("trajectory_online.csv", "online estimate", {"color": "tab:orange", "alpha": 0.7}),
                     ("trajectory_final.csv", "final estimate", {"color": "tab:green"})])
    ax.set_title(title, fontsize=9)
    written += save(fig, out, "map", formats)
    written += plot_pose_errors(d, out, formats, title)
    written += plot_gps_errors(d, out, formats, title, report)
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
    for ax, field, label in ((ax_error, "error", "final error ½Σ rᵀΩr"), (ax_time, "seconds", "time [s]")):
        ax.set_xticks(range(len(methods)))
        ax.set_xticklabels([m["name"] for m in methods], fontsize=7, rotation=30)
        plain_log_scale(ax)
        log_bar_limits(ax, [m[field] for m in methods])
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
                plain_log_scale(ax)
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
    plain_log_scale(ax)
    log_bar_limits(ax, [statistics.median(values) for values in by_method.values()])
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
    plain_log_scale(ax)
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
