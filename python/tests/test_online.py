"""The online loop driven from Python: the run's estimate, step by step."""
import numpy as np
import pytest

import subslam


def drive(slam, dataset):
    steps = dataset.steps()
    for k in range(len(steps["t"])):
        slam.predict(steps["u"][k], steps["dt"][k])
        if steps["scan"][k] >= 0:
            slam.update(**dataset.scan(int(steps["scan"][k])))
        slam.record_step(steps["t"][k])


def test_the_loop_gives_the_runs_estimate():
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=150)
    slam = subslam.Slam(dataset, frontend="rbpf", backend="eif", particles=30)
    drive(slam, dataset)
    slam.finish()
    run = subslam.run(dataset=dataset, frontend="rbpf", backend="eif", particles=30)
    assert np.array_equal(slam.final_trajectory()["poses"], run.trajectory_final.poses)
    assert np.array_equal(slam.landmarks()["positions"], run.landmarks.positions)
    assert len(slam.local_maps()) == len(run.local_maps)
    assert slam.pose.shape == (3,) and slam.pose_covariance.shape == (3, 3)


def test_a_single_map_filter_by_name():
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=30)
    slam = subslam.Slam(dataset, frontend="ekfslam", known_association=True)
    drive(slam, dataset)
    assert "EKF" in slam.name.upper()
    assert slam.landmarks()["covariances"].shape[1:] == (2, 2)
    with pytest.raises(ValueError, match="anchors"):
        slam.final_trajectory()


def test_bad_calls_raise():
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=10)
    with pytest.raises(TypeError, match="out"):
        subslam.Slam(dataset, out="/tmp/x")
    with pytest.raises(ValueError, match="particles"):
        subslam.Slam(dataset, particles=0)
    slam = subslam.Slam(dataset, frontend="ekfslam")
    with pytest.raises(ValueError, match="shape"):
        slam.update([1.0, 2.0], [0.1])
    with pytest.raises(ValueError, match="shape"):
        slam.update(np.ones((2, 2)), np.ones((2, 2)))
    with pytest.raises(ValueError, match="range"):
        slam.update([-1.0], [0.1])
    with pytest.raises(ValueError, match="detection 1"):  # the estimator's own check (CheckScan)
        slam.update([3.0, 0.0], [0.1, 0.2])
    with pytest.raises(TypeError):
        slam.predict([1.0, 2.0, 3.0], 0.1)
    with pytest.raises(ValueError, match="dt"):
        slam.predict([1.0, 0.0], -1.0)
    slam.finish()
    with pytest.raises(ValueError, match="finished"):
        slam.predict([1.0, 0.0], 0.1)


def test_a_robots_own_loop_without_scan_times():
    """A robot fills predict and update from its own controls and sensor; a scan's time defaults
    to the data set's start plus the predictions' dt, which on the simulated timeline is the
    scan's own time to rounding."""
    dataset = subslam.simulate("hybrid-120m", seed=1, duration=60)
    steps = dataset.steps()
    timed = subslam.Slam(dataset, frontend="ekfslam")
    untimed = subslam.Slam(dataset, frontend="ekfslam")
    for k in range(len(steps["t"])):
        for slam in (timed, untimed):
            slam.predict(steps["u"][k], steps["dt"][k])
        if steps["scan"][k] >= 0:
            scan = dataset.scan(int(steps["scan"][k]))
            timed.update(**scan)
            untimed.update(list(scan["ranges"]), list(scan["bearings"]))
    assert np.allclose(timed.pose, untimed.pose, atol=1e-9)
