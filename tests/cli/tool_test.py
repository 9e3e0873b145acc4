#!/usr/bin/env python3
"""The `subslam` tool as a newcomer meets it: help per command, refused flags, an output
directory the tool owns, a run repeated from its report, option errors that name the
flag, and solves that did not converge reported as such.

Run by CTest: tool_test.py --tool build/apps/subslam --data tests/data/hybrid_60s --work DIR
"""
import argparse
import filecmp
import json
import os
import re
import shutil
import subprocess
import sys
import unittest

ARGS = None


def tool(*args, check=None):
    """Runs the tool; returns (exit status, stdout, stderr)."""
    p = subprocess.run([ARGS.tool, *args], capture_output=True, text=True, timeout=300)
    if check is not None and p.returncode != check:
        raise AssertionError(f"{args}: exit {p.returncode}, expected {check}\n{p.stderr}")
    return p.returncode, p.stdout, p.stderr


def work(name):
    path = os.path.join(ARGS.work, name)
    shutil.rmtree(path, ignore_errors=True)
    return path


COMMANDS = ["simulate", "run", "calibrate", "join", "solve", "study", "study merge", "plot", "scenarios"]


class Help(unittest.TestCase):
    def test_each_command_has_its_own_help_with_status_zero(self):
        texts = {}
        for command in COMMANDS:
            status, out, _ = tool(*command.split(), "--help")
            self.assertEqual(status, 0, command)
            self.assertTrue(out.startswith(f"Usage: subslam {command}"), out[:80])
            self.assertNotIn(".cc", out, "a source path in the help")
            self.assertEqual(tool("help", *command.split())[1], out)
            self.assertEqual(tool(*command.split(), "-h")[1], out)
            texts[command] = out
        self.assertEqual(len(set(texts.values())), len(texts), "two commands print the same help")
        # Each flag a command reads is listed with its default.
        self.assertIn("--particles=100", texts["run"])
        self.assertIn("--join_merge=true", texts["join"])
        self.assertIn("--max_iterations=200", texts["solve"])
        self.assertNotIn("--particles", texts["solve"])

    def test_general_help_and_version(self):
        for args in (["help"], ["-h"], ["--help"]):
            status, out, _ = tool(*args)
            self.assertEqual(status, 0)
            for command in COMMANDS:
                self.assertIn(f"subslam {command}", out)
        status, out, _ = tool("--version")
        self.assertEqual(status, 0)
        self.assertRegex(out, r"^subslam \d+\.\d+\.\d+ \(commit ([0-9a-f]{40}(-dirty)?|unknown), \w+ build\)\n$")
        self.assertEqual(tool("help", "bogus")[0], 2)


class RefusedFlags(unittest.TestCase):
    def test_a_flag_the_choice_does_not_read_is_refused_with_its_readers(self):
        cases = [
            (["run", "--dataset", ARGS.data, "--frontend", "ekfslam", "--backend", "eif", "--particles", "5000"],
             ["--backend (read by", "--particles (read by run with --frontend fastslam or rbpf"]),
            (["run", "--dataset", ARGS.data, "--frontend", "ekfslam", "--graph", "foo.g2o"], ["--graph (read by solve"]),
            (["run", "--dataset", ARGS.data, "--frontend", "rbpf", "--backend", "none", "--join_merge=false"],
             ["--join_merge (read by"]),
            (["run", "--dataset", ARGS.data, "--frontend", "ekfslam", "--seed", "3"], ["--seed (read by"]),
            (["join", "--submaps", "x.jsonl", "--backend", "eif", "--ekf_keep_anchors"], ["--ekf_keep_anchors (read"]),
            (["solve", "--graph", "x.g2o", "--particles", "7"], ["--particles (read by"]),
        ]
        for args, expected in cases:
            status, _, err = tool(*args, "--out", work("refused"))
            self.assertEqual(status, 1, args)
            for text in expected:
                self.assertIn(text, err, args)
            self.assertFalse(os.path.exists(os.path.join(ARGS.work, "refused")), "a refused run wrote outputs")

    def test_the_manifests_own_path_names_its_data_set(self):
        status, out, err = tool("run", "--dataset", os.path.join(ARGS.data, "dataset.json"), "--frontend",
                                "odometry")
        self.assertEqual(status, 0, err)
        self.assertIn("odometry", out)
        self.assertNotIn("map: matched", out, "a map row for a run without a map")

    def test_a_stray_argument_is_named(self):
        status, _, err = tool("run", "--dataset", ARGS.data, "--frontend", "ekfslam", "stray")
        self.assertEqual(status, 1)
        self.assertIn('"stray"', err)


class OutputDirectory(unittest.TestCase):
    def run_into(self, out, *extra):
        return tool("run", "--dataset", ARGS.data, "--frontend", "ekfslam", "--quiet", "--out", out, *extra)

    def test_a_second_run_removes_the_first_runs_outputs_and_keeps_other_files(self):
        out = work("reused")
        self.run_into(out + "_rbpf", "--frontend", "rbpf", "--backend", "eif", "--progress=false")
        shutil.copytree(out + "_rbpf", out)
        with open(os.path.join(out, "notes.txt"), "w") as f:
            f.write("mine\n")
        self.assertEqual(self.run_into(out)[0], 0)
        self.assertFalse(os.path.exists(os.path.join(out, "submaps.jsonl")), "the earlier run's local maps stayed")
        self.assertFalse(os.path.exists(os.path.join(out, "joins.csv")), "the earlier run's joins stayed")
        self.assertTrue(os.path.exists(os.path.join(out, "notes.txt")))
        self.assertTrue(os.path.exists(os.path.join(out, "landmarks.csv")))

    def test_an_output_directory_of_an_earlier_version_is_reused(self):
        out = work("earlier_version")
        os.makedirs(out)
        with open(os.path.join(out, "report.json"), "w") as f:
            json.dump({"format": "subslam-report/1"}, f)
        with open(os.path.join(out, "joins.csv"), "w") as f:
            f.write("map_id,seconds\n")
        self.assertEqual(self.run_into(out)[0], 0)
        self.assertFalse(os.path.exists(os.path.join(out, "joins.csv")))

    def test_a_foreign_non_empty_directory_is_refused_and_left_alone(self):
        out = work("foreign")
        os.makedirs(out)
        with open(os.path.join(out, "thesis.csv"), "w") as f:
            f.write("1,2\n")
        status, _, err = self.run_into(out)
        self.assertEqual(status, 1)
        self.assertIn("not an output directory of subslam", err)
        self.assertEqual(os.listdir(out), ["thesis.csv"])

    def test_the_input_data_set_is_not_an_output_directory(self):
        status, _, err = self.run_into(ARGS.data)
        self.assertEqual(status, 1)
        self.assertIn(ARGS.data, err)


class Repeat(unittest.TestCase):
    def test_a_run_repeats_from_its_report_to_the_same_outputs(self):
        first, second = work("first"), work("second")
        tool("run", "--dataset", ARGS.data, "--frontend", "rbpf", "--backend", "eif", "--particles", "40",
             "--filter_seed", "5", "--join_gate", "0.99", "--quiet", "--progress=false", "--out", first, check=0)
        with open(os.path.join(first, "report.json")) as f:
            report = json.load(f)
        invocation = report["invocation"]
        self.assertEqual(invocation["command"], "run")
        self.assertIn("--particles", invocation["command_line"])
        self.assertEqual(invocation["flags"]["particles"], "40")
        self.assertEqual(invocation["flags"]["filter_seed"], "5")
        self.assertEqual(invocation["flags"]["join_gate"], "0.99")
        self.assertEqual(report["configuration"]["particle_filter"]["particles"], 40)
        self.assertIn("commit", report["build"])
        tool("run", "--config", os.path.join(first, "report.json"), "--quiet", "--progress=false", "--out", second,
             check=0)
        for name in ("trajectory_online.csv", "trajectory_final.csv", "landmarks.csv", "submaps.jsonl"):
            self.assertTrue(filecmp.cmp(os.path.join(first, name), os.path.join(second, name), shallow=False), name)
        with open(os.path.join(second, "report.json")) as f:
            again = json.load(f)
        self.assertEqual(again["metrics"], report["metrics"])
        self.assertEqual(again["invocation"]["flags"], report["invocation"]["flags"] | {"out": second, "config":
                         os.path.join(first, "report.json")})

    def test_a_config_of_another_command_is_refused(self):
        status, _, err = tool("join", "--config", os.path.join(ARGS.data, "dataset.json"), "--submaps", "x")
        self.assertEqual(status, 1)
        self.assertIn("invocation.flags", err)


class OptionErrors(unittest.TestCase):
    # Flags for which every value of their type means something.
    UNBOUNDED = {"seed", "filter_seed", "join_min_loop_pairings"}

    def context(self, readers):
        """A command line that reads a flag with these readers (docs/cli.md's column)."""
        if readers.startswith("solve"):
            return ["solve", "--graph", os.path.join(ARGS.data, "graph.g2o")]
        if readers.startswith("study"):
            return ["study", "fmj", "--out", work("never")]
        frontend = re.search(r"--frontend (\w+)", readers)
        backend = re.search(r"--backend ([\w-]+)", readers)
        args = ["run", "--scenario", "hybrid-120m", "--duration", "2", "--progress=false"]
        args += ["--frontend", frontend.group(1) if frontend else "rbpf"]
        if not frontend or frontend.group(1) in ("rbpf", "ekf"):
            args += ["--backend", backend.group(1) if backend else "eif"]
        return args

    def test_every_bad_value_names_its_flag(self):
        _, reference, _ = tool("cli-reference", check=0)
        rows = re.findall(r"^\| `--(\w+)` \| (.*?) \| .*? \| (.*?) \|$", reference, re.M)
        tested = 0
        for name, default, readers in rows:
            if name in self.UNBOUNDED:
                continue
            try:
                float(default.strip("`"))
            except ValueError:
                if default != "(none)" or name not in ("sigma_v", "sigma_range", "max_range", "trials", "workers",
                                                       "duration", "alpha", "beta", "moving_objects"):
                    continue
            refused = False
            for bad in ("-1", "nan", "1.5", "0"):
                status, _, err = tool(*self.context(readers), f"--{name}={bad}")
                if status != 0:
                    self.assertTrue(f"--{name}={bad}" in err or f"'{bad}' specified for flag '{name}'" in err or
                                    f"--{name} must" in err, f"--{name}={bad}: {err}")
                    refused = True
                    break
            self.assertTrue(refused, f"--{name}: no out-of-range value refused")
            tested += 1
        self.assertGreater(tested, 60)


class Solve(unittest.TestCase):
    def test_a_solve_stopped_at_its_iteration_limit_is_not_converged(self):
        world, out = work("graph_world"), work("solve")
        tool("simulate", "--scenario", "hybrid-120m", "--duration", "30", "--quiet", "--out", world, check=0)
        graph = os.path.join(world, "graph.g2o")
        status, table, _ = tool("solve", "--graph", graph, "--methods", "gn,lm",
                                "--max_iterations", "1", "--plots=false", "--out", out)
        self.assertEqual(status, 0)
        self.assertIn("NOT CONVERGED", table)
        with open(os.path.join(out, "report.json")) as f:
            methods = json.load(f)["methods"]
        self.assertEqual([m["converged"] for m in methods], [False, False])
        self.assertEqual(methods[0]["details"]["termination"], "NO_CONVERGENCE")
        _, table, _ = tool("solve", "--graph", graph, "--methods", "lm",
                           "--plots=false", "--out", out)
        self.assertIn("converged", table)
        self.assertNotIn("NOT CONVERGED", table)


class Calibrate(unittest.TestCase):
    def test_a_calibration_is_a_manifest_fragment_that_a_run_reads(self):
        out, run = work("calibrate"), work("calibrated_run")
        world = ["--scenario", "camera-robot", "--duration", "200"]
        status, table, err = tool("calibrate", *world, "--known_association", "--out", out)
        self.assertEqual(status, 0, err)
        self.assertIn("control_scale[0]", table)
        with open(os.path.join(out, "calibration.json")) as f:
            calibration = json.load(f)
        fragment = calibration["manifest_fragment"]
        self.assertGreater(fragment["sensor"]["sigma_range"], 0)
        self.assertEqual(len(fragment["motion"]["control_scale"]), 2)
        self.assertGreater(calibration["standard_errors"]["sensor"]["sigma_range"], 0)
        self.assertTrue(calibration["fit"]["converged"])
        self.assertTrue(calibration["detection_probability_by_range"])
        # The simulated robot drives at 0.93× and turns at 0.95× what it reports.
        scale = fragment["motion"]["control_scale"]
        se = calibration["standard_errors"]["motion"]["control_scale"]
        self.assertLess(abs(scale[0] - 0.93), 4 * se[0])
        self.assertLess(abs(scale[1] - 0.95), 4 * se[1])
        status, _, err = tool("run", *world, "--frontend", "ekfslam", "--quiet",
                              "--calibration", os.path.join(out, "calibration.json"), "--out", run)
        self.assertEqual(status, 0, err)
        with open(os.path.join(run, "report.json")) as f:
            self.assertIn("--calibration", json.dumps(json.load(f)["invocation"]))

    def test_a_bad_calibration_file_names_the_file_and_the_field(self):
        bad = os.path.join(work("bad_calibration"), "calibration.json")
        os.makedirs(os.path.dirname(bad))
        with open(bad, "w") as f:
            f.write('{"manifest_fragment": {"sensor": {"sigma_range": -1}}}')
        status, _, err = tool("run", "--dataset", ARGS.data, "--frontend", "ekfslam", "--calibration", bad)
        self.assertEqual(status, 1)
        self.assertIn(bad, err)
        self.assertIn("manifest_fragment.sensor.sigma_range", err)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--tool", required=True)
    parser.add_argument("--data", required=True)
    parser.add_argument("--work", required=True)
    ARGS, rest = parser.parse_known_args()
    ARGS.data = os.path.abspath(ARGS.data)
    os.makedirs(ARGS.work, exist_ok=True)
    unittest.main(argv=[sys.argv[0], *rest])
