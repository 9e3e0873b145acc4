"""The Python example and benchmark scripts run (on a short simulated data set)."""
import os
import subprocess
import sys

import pytest

import subslam

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    directory = tmp_path_factory.mktemp("data")
    subslam.simulate("hybrid-120m", seed=1, duration=120).write(str(directory))
    return str(directory)


def run_script(*args):
    return subprocess.run([sys.executable, *args], check=True, capture_output=True, text=True,
                          env=dict(os.environ)).stdout


def test_the_compare_backends_example_draws_its_figure(small_dataset, tmp_path):
    out = run_script(os.path.join(ROOT, "examples", "python", "compare_backends.py"), small_dataset,
                     "--out", str(tmp_path))
    assert "ceres (join)" in out
    assert os.path.getsize(tmp_path / "compare_backends.png") > 0


def test_the_online_loop_benchmark_runs(small_dataset):
    out = run_script(os.path.join(ROOT, "bench", "python_online_loop.py"), small_dataset)
    assert "local maps joined into" in out
