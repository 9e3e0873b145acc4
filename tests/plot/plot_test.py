#!/usr/bin/python3
"""`subslam plot` (scripts/plot.py) on real outputs, and the figures a complete study draws
itself: they hold what they claim (one ellipse per estimated landmark drawn above the points,
one curve per method, the χ² band, the distance to each GPS fix at the metric's RMS, plain
numbers on log axes), not only that the files exist.

  plot_test.py --tool build/apps/subslam --data tests/data/hybrid_60s --work DIR
"""
import argparse
import csv
import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import sys
import unittest
import xml.etree.ElementTree as ET

import numpy as np

ARGS = None
# The script the tool runs from the source tree, imported for its helpers.
SPEC = importlib.util.spec_from_file_location(
    "plot", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts", "plot.py"))
PLOT = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(PLOT)
# What a plain tick label looks like: 0.01, 5, 300, 1e-5, 1e30 (not mathtext's $10^{-1}$ or 2×10⁰).
PLAIN_NUMBER = re.compile(r"^-?\d+(\.\d+)?(e-?\d+)?$")


def svg_ids(path):
    return {e.get("id") for e in ET.parse(path).iter() if e.get("id")}


def svg_ids_in_order(path):
    """The ids of an SVG's elements in document order, which is matplotlib's drawing order."""
    return [e.get("id") for e in ET.parse(path).iter() if e.get("id")]


def svg_texts(path, under=""):
    """The texts matplotlib drew (it keeps each one as a comment beside its glyphs), those under
    elements whose id starts with `under` when given."""
    root = ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))).getroot()
    groups = [e for e in root.iter() if (e.get("id") or "").startswith(under)] if under else [root]
    return [c.text.strip() for g in groups for c in g.iter() if c.tag is ET.Comment]


def write_gps_dataset(source, out):
    """`source` (a simulated data set) as a real one is given: its true poses become GPS fixes
    once a second, in the receiver's own frame (turned 0.4 rad and moved by (250, -80) m) with
    a few centimetres of noise, one fix 200 m off (a gross fault) and an outage of 8 s; no true
    poses or landmarks."""
    shutil.copytree(source, out)
    truth = np.loadtxt(os.path.join(source, "truth_poses.dat"), comments="#")
    c, s = math.cos(0.4), math.sin(0.4)
    with open(os.path.join(out, "gps.dat"), "w") as f:
        f.write("# t x y\n")
        for k, (t, x, y, _) in enumerate(truth[::10]):
            if 20 <= k < 28:
                continue  # the outage
            noise = 0.03 * math.sin(7.0 * k), 0.03 * math.cos(5.0 * k)
            gx, gy = 250 + c * x - s * y + noise[0], -80 + s * x + c * y + noise[1]
            if k == 40:
                gx += 200
            f.write(f"{t:.3f} {gx:.4f} {gy:.4f}\n")
    with open(os.path.join(out, "dataset.json")) as f:
        manifest = json.load(f)
    manifest["ground_truth"] = {"gps_file": "gps.dat", "poses_file": None, "landmarks_file": None}
    with open(os.path.join(out, "dataset.json"), "w") as f:
        json.dump(manifest, f, indent=2)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def run(*cmd):
    p = subprocess.run(list(cmd), capture_output=True, text=True)
    if p.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)}\n{p.stdout}\n{p.stderr}")
    return p.stdout


class PlotTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        shutil.rmtree(ARGS.work, ignore_errors=True)
        cls.run_dir = os.path.join(ARGS.work, "run")
        run(ARGS.tool, "run", "--dataset", ARGS.data, "--frontend", "rbpf", "--backend", "eif", "--quiet",
            "--progress=false", "--out", cls.run_dir)
        cls.gps_dir = os.path.join(ARGS.work, "gps_run")
        write_gps_dataset(ARGS.data, os.path.join(ARGS.work, "gps_data"))
        run(ARGS.tool, "run", "--dataset", os.path.join(ARGS.work, "gps_data"), "--frontend", "rbpf", "--backend",
            "eif", "--quiet", "--progress=false", "--out", cls.gps_dir)
        run(ARGS.tool, "plot", cls.run_dir, cls.gps_dir)

    def assert_log_ticks_plain(self, path):
        labels = [t for t in svg_texts(path, "ytick_") if t]
        self.assertTrue(labels, path)
        for label in labels:
            self.assertRegex(label, PLAIN_NUMBER, path)

    def test_run_map_has_one_ellipse_per_landmark(self):
        out = run(ARGS.tool, "plot", self.run_dir)
        for name in ("map", "nees", "errors", "joins"):
            self.assertIn(os.path.join(self.run_dir, "plots", f"{name}.svg"), out)
            self.assertTrue(os.path.getsize(os.path.join(self.run_dir, "plots", f"{name}.png")) > 0)
        self.assertNotIn("gps_errors", out)  # no GPS in a simulated world
        ids = svg_ids(os.path.join(self.run_dir, "plots", "map.svg"))
        landmarks = rows(os.path.join(self.run_dir, "landmarks.csv"))
        self.assertGreater(len(landmarks), 5)
        self.assertEqual({i for i in ids if i.startswith("landmark-ellipse-")},
                         {f"landmark-ellipse-{r['id']}" for r in landmarks})
        for gid in ("truth-landmarks", "truth-trajectory", "trajectory_online", "trajectory_final"):
            self.assertIn(gid, ids)
        nees = svg_ids(os.path.join(self.run_dir, "plots", "nees.svg"))
        self.assertTrue({"nees-online", "nees-final", "nees-band"} <= nees, nees)
        self.assert_log_ticks_plain(os.path.join(self.run_dir, "plots", "nees.svg"))

    def test_map_draws_the_ellipses_above_every_point_and_line(self):
        for d in (self.run_dir, self.gps_dir):
            order = svg_ids_in_order(os.path.join(d, "plots", "map.svg"))
            ellipses = [k for k, i in enumerate(order) if i.startswith("landmark-ellipse-")]
            below = [k for k, i in enumerate(order) if i in ("truth-landmarks", "landmarks", "gps", "gps-rejected",
                                                               "truth-trajectory", "trajectory_online",
                                                               "trajectory_final")]
            self.assertTrue(ellipses and below, order)
            self.assertGreater(min(ellipses), max(below), d)

    def test_gps_run_draws_the_distance_to_each_fix(self):
        plots = os.path.join(self.gps_dir, "plots")
        self.assertFalse(os.path.exists(os.path.join(plots, "nees.svg")))  # no true poses
        ids = svg_ids(os.path.join(plots, "gps_errors.svg"))
        self.assertTrue({"gps-error-online", "gps-error-final", "gps-fault-0"} <= ids, ids)
        self.assertIn("gps", svg_ids(os.path.join(plots, "map.svg")))
        # The distances are those the metrics summarise: the same fixes, RMS and maximum, and
        # the legend gives each RMS.
        with open(os.path.join(self.gps_dir, "report.json")) as f:
            metrics = json.load(f)["metrics"]
        distances, faults = PLOT.gps_distances(self.gps_dir, {"metrics": metrics})
        self.assertEqual(len(faults), 1)
        texts = svg_texts(os.path.join(plots, "gps_errors.svg"))
        for kind in ("online", "final"):
            metric = metrics[f"gps_{kind}"]
            t, distance = distances[kind]
            self.assertEqual(len(t), metric["matched_fixes"])
            self.assertEqual(len(distance), metric["matched_fixes"])
            self.assertAlmostEqual(math.sqrt(np.mean(distance ** 2)), metric["aligned_rms_m"], places=4)
            self.assertAlmostEqual(float(np.max(distance)), metric["aligned_max_m"], places=4)
            self.assertIn(f"{kind} (RMS {metric['aligned_rms_m']:.3g} m)", texts)

    def test_log_axes_label_major_and_minor_ticks_as_plain_numbers(self):
        # Less than a decade (2 to 8): matplotlib's default would write 2×10⁰ … on minor ticks.
        fig, ax = PLOT.plt.subplots()
        ax.plot([0, 1], [2, 8])
        PLOT.plain_log_scale(ax)
        fig.canvas.draw()
        minor = [t.get_text() for t in ax.get_yticklabels(minor=True) if t.get_text()]
        self.assertTrue({"2", "3", "5"} <= set(minor), minor)
        for label in minor + [t.get_text() for t in ax.get_yticklabels() if t.get_text()]:
            self.assertRegex(label, PLAIN_NUMBER)
        # Thirty decades (a diverged NEES): decades only, in short exponent form beyond 10⁶.
        ax.set_ylim(1e-3, 1e30)
        fig.canvas.draw()
        self.assertFalse([t.get_text() for t in ax.get_yticklabels(minor=True) if t.get_text()])
        self.assertEqual(PLOT.plain_number(1e30), "1e30")
        self.assertEqual(PLOT.plain_number(1e-5), "1e-5")
        self.assertEqual(PLOT.plain_number(0.002), "0.002")
        PLOT.plt.close(fig)

    def test_join_map_draws_the_anchors(self):
        join_dir = os.path.join(ARGS.work, "join")
        run(ARGS.tool, "join", "--submaps", os.path.join(self.run_dir, "submaps.jsonl"), "--backend", "eif",
            "--dataset", ARGS.data, "--quiet", "--out", join_dir)
        run(ARGS.tool, "plot", join_dir, "--quiet")
        ids = svg_ids(os.path.join(join_dir, "plots", "map.svg"))
        self.assertIn("anchors", ids)
        self.assertEqual(len([i for i in ids if i.startswith("landmark-ellipse-")]),
                         len(rows(os.path.join(join_dir, "landmarks.csv"))))

    def test_solve_draws_each_solution_and_error(self):
        sim = os.path.join(ARGS.work, "sim")
        run(ARGS.tool, "simulate", "--scenario", "hybrid-120m", "--duration", "20", "--out", sim)
        solve = os.path.join(ARGS.work, "solve")
        run(ARGS.tool, "solve", "--graph", os.path.join(sim, "graph.isam"), "--methods", "lm,submaps-lm",
            "--quiet", "--out", solve)
        ids = svg_ids(os.path.join(solve, "plots", "solutions.svg"))
        for method in ("lm", "submaps-lm"):
            self.assertIn(f"solution-poses-{method}", ids)
            self.assertIn(f"solution-points-{method}", ids)
        errors = svg_ids(os.path.join(solve, "plots", "errors.svg"))
        self.assertTrue({"error-lm", "error-submaps-lm", "seconds-lm", "seconds-submaps-lm"} <= errors, errors)
        self.assert_log_ticks_plain(os.path.join(solve, "plots", "errors.svg"))

    def test_monte_carlo_study_has_one_curve_per_method_and_the_band(self):
        study = os.path.join(ARGS.work, "fmj")
        run(ARGS.tool, "study", "fmj", "--trials", "2", "--methods", "fmj,ekfslam", "--quiet", "--out", study)
        for case in (1, 2):
            ids = svg_ids(os.path.join(study, "plots", f"anees-fmj_case{case}.svg"))
            self.assertTrue({"anees-fmj", "anees-ekfslam", "anees-band"} <= ids, ids)
            self.assertNotIn("anees-fmj-fixed", ids)
        self.assertTrue({"timing-fmj", "timing-ekfslam"} <= svg_ids(os.path.join(study, "plots", "timings.svg")))
        for name in ("anees-fmj_case1", "consistency-fmj_case1", "timings", "join_times"):
            self.assert_log_ticks_plain(os.path.join(study, "plots", f"{name}.svg"))
        # Only fmj joins local maps: one joining-time curve per case.
        self.assertEqual({i for i in svg_ids(os.path.join(study, "plots", "join_times.svg")) if i.startswith("join-time-")},
                         {"join-time-fmj-fmj_case-1", "join-time-fmj-fmj_case-2"})

    def test_hybridslam_study_has_a_bar_per_method_and_setting(self):
        study = os.path.join(ARGS.work, "hybridslam")
        run(ARGS.tool, "study", "hybridslam", "--trials", "1", "--methods", "ekf", "--quiet", "--out", study)
        ids = svg_ids(os.path.join(study, "plots", "success.svg"))
        self.assertEqual({i for i in ids if i.startswith("success-")}, {f"success-ekf-{s}" for s in range(4)})

    def test_a_slice_is_refused(self):
        study = os.path.join(ARGS.work, "slice")
        run(ARGS.tool, "study", "fmj", "--trials", "1", "--methods", "ekfslam", "--shard", "1/2", "--quiet",
            "--out", study)
        self.assertFalse(os.path.exists(os.path.join(study, "plots")))
        p = subprocess.run([ARGS.tool, "plot", study], capture_output=True, text=True)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("merge", p.stderr)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--tool", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--work", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
