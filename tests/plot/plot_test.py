#!/usr/bin/python3
"""`subslam plot` (scripts/plot.py) on real outputs, and the figures a complete study draws
itself: they hold what they claim (one ellipse per estimated landmark, one curve per
method, the χ² band), not only that the files exist.

  plot_test.py --tool build/apps/subslam --data tests/data/hybrid_60s --work DIR
"""
import argparse
import csv
import os
import shutil
import subprocess
import sys
import unittest
import xml.etree.ElementTree as ET

ARGS = None


def svg_ids(path):
    return {e.get("id") for e in ET.parse(path).iter() if e.get("id")}


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

    def test_run_map_has_one_ellipse_per_landmark(self):
        out = run(ARGS.tool, "plot", self.run_dir)
        for name in ("map", "nees", "errors", "joins"):
            self.assertIn(os.path.join(self.run_dir, "plots", f"{name}.svg"), out)
            self.assertTrue(os.path.getsize(os.path.join(self.run_dir, "plots", f"{name}.png")) > 0)
        ids = svg_ids(os.path.join(self.run_dir, "plots", "map.svg"))
        landmarks = rows(os.path.join(self.run_dir, "landmarks.csv"))
        self.assertGreater(len(landmarks), 5)
        self.assertEqual({i for i in ids if i.startswith("landmark-ellipse-")},
                         {f"landmark-ellipse-{r['id']}" for r in landmarks})
        for gid in ("truth-landmarks", "truth-trajectory", "trajectory_online", "trajectory_final"):
            self.assertIn(gid, ids)
        nees = svg_ids(os.path.join(self.run_dir, "plots", "nees.svg"))
        self.assertTrue({"nees-online", "nees-final", "nees-band"} <= nees, nees)

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

    def test_monte_carlo_study_has_one_curve_per_method_and_the_band(self):
        study = os.path.join(ARGS.work, "fmj")
        run(ARGS.tool, "study", "fmj", "--trials", "2", "--methods", "fmj,ekfslam", "--quiet", "--out", study)
        for case in (1, 2):
            ids = svg_ids(os.path.join(study, "plots", f"anees-fmj_case{case}.svg"))
            self.assertTrue({"anees-fmj", "anees-ekfslam", "anees-band"} <= ids, ids)
            self.assertNotIn("anees-fmj-fixed", ids)
        self.assertTrue({"timing-fmj", "timing-ekfslam"} <= svg_ids(os.path.join(study, "plots", "timings.svg")))
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
