"""Data sets and local maps as numpy arrays, and the errors bad arguments raise."""
import numpy as np
import pytest

import subslam


def test_a_simulated_data_set_as_arrays():
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=60)
    controls = dataset.controls
    assert controls["u"].shape == (len(controls["t"]), 2)
    steps = dataset.steps()
    assert steps["u"].shape == (len(steps["t"]), 2) and steps["dt"][0] == 0.0
    scans = steps["scan"][steps["scan"] >= 0]
    assert np.array_equal(scans, np.arange(dataset.num_scans))
    scan = dataset.scan(0)
    assert scan["ranges"].shape == scan["bearings"].shape == scan["truth_ids"].shape
    assert sum(len(dataset.scan(i)["ranges"]) for i in range(dataset.num_scans)) == dataset.num_detections
    truth = dataset.truth
    assert truth["poses"]["poses"].shape[1] == 3 and truth["landmarks"]["positions"].shape[1] == 2
    assert dataset.models["sensor"]["has_truth_id"]


def test_a_written_data_set_reads_back(tmp_path):
    dataset = subslam.simulate("fmj-ellipse", seed=2, duration=30)
    dataset.write(str(tmp_path))
    again = subslam.read_dataset(str(tmp_path))
    assert again.num_detections == dataset.num_detections
    assert np.allclose(again.controls["u"], dataset.controls["u"])


def test_bad_data_arguments_raise():
    with pytest.raises(FileNotFoundError):
        subslam.read_dataset("/no/such/dir")
    with pytest.raises(TypeError, match="particles"):
        subslam.simulate("hybrid-120m", particles=3)
    with pytest.raises(ValueError, match="no-such"):
        subslam.simulate("no-such")
    with pytest.raises(TypeError, match="Dataset.write"):
        subslam.simulate("hybrid-120m", out="/tmp/x")
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=10)
    with pytest.raises(IndexError):
        dataset.scan(dataset.num_scans)


def test_a_local_map_from_arrays_is_checked_and_joins():
    covariance = np.diag([0.01, 0.01, 0.001, 0.04, 0.04])
    first = subslam.LocalMap(0, 0.0, 1.0, [1.0, 0.0, 0.0, 3.0, 2.0], covariance, feature_ids=[7])
    second = subslam.LocalMap(1, 1.0, 2.0, [1.0, 0.0, 0.0, 2.0, 2.0], covariance, feature_ids=[3])
    assert first.feature_ids == [7] and first.num_landmarks == 1
    assert np.array_equal(first.end_pose, [1.0, 0.0, 0.0])
    joined = subslam.join([first, second], backend="eif")
    assert joined.anchors.poses.shape == (3, 3)
    assert len(joined.landmarks.ids) == 1  # the same landmark seen from both maps
    assert np.allclose(joined.landmarks.positions[0], [3.0, 2.0], atol=1e-6)


@pytest.mark.parametrize("mean, covariance, words", [
    ([1.0, 0.0, 0.0, 3.0], np.eye(4), "3 \\+ 2n"),
    ([1.0, 0.0, 0.0], np.eye(4), "shape"),
    ([1.0, 0.0, 0.0], -np.eye(3), "definite"),
    ([1.0, 0.0, float("nan")], np.eye(3), "finite"),
])
def test_a_bad_local_map_raises(mean, covariance, words):
    with pytest.raises(ValueError, match=words):
        subslam.LocalMap(0, 0.0, 1.0, mean, covariance)


def test_local_maps_read_and_write(tmp_path):
    maps = [subslam.LocalMap(0, 0.0, 1.0, [1.0, 0.0, 0.0], np.eye(3) * 1e-3)]
    subslam.write_local_maps(str(tmp_path / "m.jsonl"), maps)
    again = subslam.read_local_maps(str(tmp_path / "m.jsonl"))
    assert len(again) == 1 and np.array_equal(again[0].mean, maps[0].mean)


def test_a_malformed_data_set_names_the_file_line_and_field(tmp_path):
    subslam.simulate("hybrid-120m", seed=1, duration=10).write(str(tmp_path))
    controls = tmp_path / "controls.dat"
    lines = controls.read_text().splitlines()
    data_line = next(i for i, line in enumerate(lines) if line.strip() and not line.startswith("#"))
    lines[data_line] = "0.5 not-a-number 0.1"
    controls.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=f"controls.dat:{data_line + 1}"):
        subslam.read_dataset(str(tmp_path))
