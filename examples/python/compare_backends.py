#!/usr/bin/env python3
"""Victoria Park from Python: RBPF local maps joined by two back-ends, the maps plotted.

Runs the flagship (RBPF local maps joined by the EIF) on a data set, joins the same local
maps again with the Ceres back-end, prints each back-end's landmarks, time and error against
the GPS (or the truth, for a simulated data set), and draws both maps over the GPS track
into OUT/compare_backends.png:

    PYTHONPATH=build/python /usr/bin/python3 examples/python/compare_backends.py \\
        ../shared/data/victoria_park --out runs/py_vp
"""
import argparse
import os

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import subslam  # noqa: E402


def error_against_ground_truth(report, prefix):
    """The aligned RMS against the GPS [m] or the RMS against the true poses, as the report has it."""
    metrics = report.get("metrics", {})
    for key, field in ((f"gps_{prefix}", "aligned_rms_m"), (prefix, "rms_position_m")):
        if key in metrics and field in metrics[key]:
            return metrics[key][field], key
    return float("nan"), "none"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", help="a data-set directory (dataset.json)")
    parser.add_argument("--out", default="runs/py_compare_backends", help="where the figure goes")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    dataset = subslam.read_dataset(args.dataset)
    run = subslam.run(dataset=dataset, frontend="rbpf", backend="eif")  # the flagship
    ceres = subslam.join(run.local_maps, backend="ceres", dataset=args.dataset)

    rows = [("eif (run)", run.landmarks, run.trajectory_final.poses, run.report, "final"),
            ("ceres (join)", ceres.landmarks, ceres.anchors.poses, ceres.report, "anchors")]
    print(f"{len(run.local_maps)} local maps from {dataset.name}")
    print(f"{'back-end':14} {'landmarks':>9} {'seconds':>8} {'RMS [m]':>8}  against")
    for name, landmarks, _, report, prefix in rows:
        rms, against = error_against_ground_truth(report, prefix)
        print(f"{name:14} {len(landmarks.ids):9d} {report['time_seconds']['total']:8.2f} {rms:8.2f}  {against}")

    figure, axes = plt.subplots(1, 2, figsize=(12, 6), sharex=True, sharey=True)
    for axis, (name, landmarks, poses, report, _) in zip(axes, rows):
        gps = report.get("metrics", {}).get("gps_final" if name.startswith("eif") else "gps_anchors", {})
        if dataset.gps["t"].size and "gps_T_estimate" in gps:  # the GPS in the estimate's frame
            x, y, theta = gps["gps_T_estimate"]
            c, s = np.cos(theta), np.sin(theta)
            p = dataset.gps["positions"]
            estimate_frame = np.column_stack([c * (p[:, 0] - x) + s * (p[:, 1] - y),
                                              -s * (p[:, 0] - x) + c * (p[:, 1] - y)])
            axis.plot(estimate_frame[:, 0], estimate_frame[:, 1], ".", ms=1, color="0.7", label="GPS")
        axis.plot(poses[:, 0], poses[:, 1], "-", lw=0.6, color="tab:blue", label="vehicle")
        axis.plot(landmarks.positions[:, 0], landmarks.positions[:, 1], "+", color="tab:red", ms=4,
                  label=f"{len(landmarks.ids)} landmarks")
        axis.set_title(name)
        axis.set_aspect("equal")
        axis.set_xlabel("x [m]")
        axis.legend(loc="best", fontsize=8)
    axes[0].set_ylabel("y [m]")
    figure.tight_layout()
    path = os.path.join(args.out, "compare_backends.png")
    figure.savefig(path, dpi=120)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
