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


def test_the_notebook_runs(small_dataset, tmp_path):
    pytest.importorskip("nbconvert")
    path = os.pathsep.join(os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p)
    env = dict(os.environ, SUBSLAM_DATASET=small_dataset, PYTHONPATH=path, PYDEVD_DISABLE_FILE_VALIDATION="1")
    notebook = os.path.join(ROOT, "examples", "python", "victoria_park.ipynb")
    subprocess.run([sys.executable, "-m", "nbconvert", "--to", "notebook", "--execute", notebook,
                    "--output-dir", str(tmp_path), "--output", "executed.ipynb"],
                   check=True, capture_output=True, text=True, env=env)
    import nbformat
    executed = nbformat.read(str(tmp_path / "executed.ipynb"), as_version=4)
    images = [o for c in executed.cells for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(images) == 2  # the two maps, the position sd over time
