"""Shared fixtures of the Python tests: the tool beside the module (to compare with) and the
data sets, which are optional (their tests are skipped without them)."""
import os
import subprocess

import pytest


@pytest.fixture(scope="module")
def tool():
    """Runs the `subslam` tool of the same build; returns its completed process."""
    path = os.environ.get("SUBSLAM_TOOL", "")
    if not path or not os.path.exists(path):
        pytest.skip("SUBSLAM_TOOL (the subslam tool of this build) is not set")

    def run(*args):
        return subprocess.run([path, *args, "--quiet"], check=True, capture_output=True, text=True)
    return run


def data_dir(variable):
    path = os.environ.get(variable, "")
    if not path or not os.path.isdir(path):
        pytest.skip(f"{variable} is not a directory")
    return path


@pytest.fixture(scope="module")
def victoria_park():
    return data_dir("SUBSLAM_VICTORIA_PARK_DIR")


@pytest.fixture(scope="module")
def graphs():
    return data_dir("SUBSLAM_GRAPHS_DIR")


def same_files(a, b, names):
    """Whether each named file is byte for byte the same in directories a and b."""
    for name in names:
        with open(os.path.join(a, name), "rb") as fa, open(os.path.join(b, name), "rb") as fb:
            if fa.read() != fb.read():
                return name
    return None
