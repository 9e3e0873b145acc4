#!/usr/bin/python3
"""The odometry of a data set against its ground truth, window by window: is its error white
Gaussian noise as the manifest's motion model says, or does it carry a scale bias and heavy
tails? (numpy, Debian's python3-numpy)

  scripts/odometry_residuals.py DATASET_DIR [--window 1.0] [--scale 1.0]

Needs a `unicycle` data set with `ground_truth.poses_file` (docs/formats.md). For each window
of W seconds it compares the heading change the truth shows with the one the controls
command (held until the next line, turn rate times `--scale`), and reads the residual
against the motion model's own variance over the window, σ_ω² Σ dt² (the noise is per
control, docs/formats.md). Printed: the least-squares turn scale, the residuals' RMS,
the model's σ, and the normalised squared residual (NIS, one dof): mean and median (1 and
0.45 for a model that fits), the fraction beyond χ²₁(0.99) = 6.63 (1 %), and the share of
the NIS sum in the largest 5 % of windows (0.28 for Gaussian residuals).
"""
import argparse
import json
import os
import sys

import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--window", type=float, default=1.0, help="window length [s]")
    parser.add_argument("--scale", type=float, default=None, help="turn scale (default: fitted)")
    args = parser.parse_args()
    with open(os.path.join(args.dataset, "dataset.json")) as f:
        manifest = json.load(f)
    motion = manifest["motion"]
    if motion.get("model") != "unicycle" or not manifest.get("ground_truth", {}).get("poses_file"):
        sys.exit(f"{args.dataset}: needs a unicycle data set with ground_truth.poses_file")
    controls = np.loadtxt(os.path.join(args.dataset, motion["controls_file"]), comments="#", ndmin=2)
    truth = np.loadtxt(os.path.join(args.dataset, manifest["ground_truth"]["poses_file"]), comments="#", ndmin=2)
    sigma_omega = float(motion["sigma_omega"])
    t = controls[:, 0]
    dt = np.diff(t)
    # Cumulative commanded heading and Σ dt² at each control time (a control holds until the next).
    commanded = np.concatenate([[0.0], np.cumsum(controls[:-1, 2] * dt)])
    dt2 = np.concatenate([[0.0], np.cumsum(dt * dt)])
    heading = np.unwrap(truth[:, 3])
    w = args.window
    starts = np.arange(max(t[0], truth[0, 0]), min(t[-1], truth[-1, 0]) - w, w)
    true_turn = np.interp(starts + w, truth[:, 0], heading) - np.interp(starts, truth[:, 0], heading)
    cmd_turn = np.interp(starts + w, t, commanded) - np.interp(starts, t, commanded)
    variance = sigma_omega**2 * (np.interp(starts + w, t, dt2) - np.interp(starts, t, dt2))
    scale = args.scale
    if scale is None:
        scale = float(np.dot(true_turn, cmd_turn) / np.dot(cmd_turn, cmd_turn))
    residual = true_turn - scale * cmd_turn
    nis = residual**2 / variance
    top = np.sort(nis)[::-1][: max(1, len(nis) // 20)]
    print(f"{len(starts)} windows of {w:g} s, turn scale {scale:.3f}")
    print(f"heading residual RMS {np.sqrt(np.mean(residual ** 2)):.4f} rad, model sigma (median) "
          f"{np.median(np.sqrt(variance)):.4f} rad")
    print(f"NIS mean {nis.mean():.2f}, median {np.median(nis):.2f}, beyond 6.63: {np.mean(nis > 6.63):.3f}, "
          f"share of the largest 5 %: {top.sum() / nis.sum():.2f}")


if __name__ == "__main__":
    main()
