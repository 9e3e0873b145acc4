"""The jobs from Python are the tool's jobs: the same options give the same outputs, to the bit."""
import json
import os
import threading

import numpy as np
import pytest

import subslam
from conftest import same_files

RUN_FILES = ["trajectory_online.csv", "trajectory_final.csv", "landmarks.csv", "submaps.jsonl"]


def without_times(report):
    """report.json without what differs between two runs of the same job: times, memory, the
    invocation, and the particle filter's count of scans run on fewer threads than its pool
    (it follows the back-end's background joins' timing)."""
    kept = {k: v for k, v in report.items()
            if k not in ("time_seconds", "peak_rss_kb", "rss_kb_by_tenth_of_steps", "invocation", "build")}
    kept["estimator_counters"] = {k: v for k, v in kept.get("estimator_counters", {}).items()
                                  if k != "scans_with_fewer_threads"}
    return kept


def read_report(directory):
    with open(os.path.join(directory, "report.json")) as f:
        return json.load(f)


def test_run_is_the_tools_run(tool, tmp_path):
    options = dict(scenario="hybrid-120m", seed=2, frontend="rbpf", backend="eif", particles=50)
    result = subslam.run(out=str(tmp_path / "py"), **options)
    tool("run", "--scenario=hybrid-120m", "--seed=2", "--frontend=rbpf", "--backend=eif", "--particles=50",
         f"--out={tmp_path / 'tool'}")
    assert same_files(tmp_path / "py", tmp_path / "tool", RUN_FILES) is None
    assert without_times(read_report(tmp_path / "py")) == without_times(read_report(tmp_path / "tool"))
    assert without_times(result.report) == without_times(read_report(tmp_path / "tool"))
    # The arrays are the estimates the files were written from.
    final = np.loadtxt(tmp_path / "tool" / "trajectory_final.csv", delimiter=",", skiprows=1)
    assert np.allclose(result.trajectory_final.poses, final[:, 1:4], rtol=1e-9, atol=1e-9)
    assert result.trajectory_final.covariances.shape == (len(final), 3, 3)
    landmarks = np.loadtxt(tmp_path / "tool" / "landmarks.csv", delimiter=",", skiprows=1, ndmin=2)
    assert np.array_equal(result.landmarks.ids, landmarks[:, 0].astype(int))
    assert len(result.local_maps) == sum(1 for _ in open(tmp_path / "tool" / "submaps.jsonl"))
    assert result.stopped is None


def test_the_tool_repeats_a_python_run_from_its_report(tool, tmp_path):
    subslam.run(scenario="hybrid-120m", seed=3, frontend="ekfslam", sigma_range=0.08, out=str(tmp_path / "py"))
    tool("run", f"--config={tmp_path / 'py' / 'report.json'}", f"--out={tmp_path / 'again'}")
    assert same_files(tmp_path / "py", tmp_path / "again", ["trajectory_online.csv", "landmarks.csv"]) is None


def test_a_dataset_in_memory_runs_as_its_directory(tmp_path):
    dataset = subslam.simulate("hybrid-120m", seed=4, duration=120)
    dataset.write(str(tmp_path / "data"))
    from_memory = subslam.run(dataset=dataset, frontend="ekfslam")
    from_disk = subslam.run(dataset=str(tmp_path / "data"), frontend="ekfslam")
    assert np.array_equal(from_memory.trajectory_online.poses, from_disk.trajectory_online.poses)
    assert np.array_equal(from_memory.landmarks.positions, from_disk.landmarks.positions)


def test_join_is_the_tools_join_from_a_file_or_from_local_map_objects(tool, tmp_path):
    subslam.run(scenario="hybrid-120m", seed=1, frontend="rbpf", particles=30, out=str(tmp_path / "run"))
    submaps = str(tmp_path / "run" / "submaps.jsonl")
    from_file = subslam.join(submaps, backend="eif", scenario="hybrid-120m", seed=1, out=str(tmp_path / "py"))
    from_objects = subslam.join(subslam.read_local_maps(submaps), backend="eif", scenario="hybrid-120m", seed=1)
    tool("join", f"--submaps={submaps}", "--backend=eif", "--scenario=hybrid-120m", "--seed=1",
         f"--out={tmp_path / 'tool'}")
    assert same_files(tmp_path / "py", tmp_path / "tool", ["anchors.csv", "landmarks.csv", "graph.g2o"]) is None
    assert np.array_equal(from_file.anchors.poses, from_objects.anchors.poses)
    assert np.array_equal(from_file.landmarks.positions, from_objects.landmarks.positions)
    assert from_file.report["metrics"] == read_report(tmp_path / "tool")["metrics"]


def test_solve_is_the_tools_solve_on_the_shipped_graph(tool, graphs, tmp_path):
    graph = os.path.join(graphs, "victoria_park.txt")
    methods = "submaps,eif"
    result = subslam.solve(graph, format="gtsam", methods=methods.split(","), out=str(tmp_path / "py"), plots=False)
    tool("solve", f"--graph={graph}", "--format=gtsam", f"--methods={methods}", f"--out={tmp_path / 'tool'}",
         "--noplots")
    assert same_files(tmp_path / "py", tmp_path / "tool", ["submaps.g2o", "eif.g2o"]) is None
    errors = {m["name"]: m["error"] for m in result.report["methods"]}
    assert errors == {m["name"]: m["error"] for m in read_report(tmp_path / "tool")["methods"]}
    # The graph cut into local maps, joined by the tree EIF with the graph's association.
    subslam.solve(graph, format="gtsam", methods=["submaps"], write_local_maps=True, out=str(tmp_path / "maps"),
                  plots=False)
    submaps = str(tmp_path / "maps" / "submaps_submaps.jsonl")
    subslam.join(submaps, backend="tree-eif", known_association=True, out=str(tmp_path / "join_py"))
    tool("join", f"--submaps={submaps}", "--backend=tree-eif", "--known_association", f"--out={tmp_path / 'join'}")
    assert same_files(tmp_path / "join_py", tmp_path / "join", ["anchors.csv", "landmarks.csv", "graph.g2o"]) is None


def test_victoria_park_from_python_is_the_tools_run(tool, victoria_park, tmp_path):
    result = subslam.run(dataset=victoria_park, frontend="rbpf", backend="eif", out=str(tmp_path / "py"))
    tool("run", f"--dataset={victoria_park}", "--frontend=rbpf", "--backend=eif", f"--out={tmp_path / 'tool'}")
    assert same_files(tmp_path / "py", tmp_path / "tool", RUN_FILES) is None
    assert result.report["metrics"] == read_report(tmp_path / "tool")["metrics"]


def test_a_study_returns_its_summary(tmp_path):
    result = subslam.study("hybridslam", trials=1, methods=["ekf"], workers=1, out=str(tmp_path / "s"),
                           plots=False)
    assert result.summary is not None and os.path.exists(tmp_path / "s" / "runs.csv")


def test_runs_on_two_threads_give_the_runs_of_one_thread():
    options = [dict(scenario="hybrid-120m", seed=s, frontend="ekfslam", duration=200) for s in (5, 6)]
    alone = [subslam.run(**o) for o in options]
    together = [None, None]

    def work(i):
        together[i] = subslam.run(**options[i])
    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, together):
        assert np.array_equal(a.trajectory_online.poses, b.trajectory_online.poses)


@pytest.mark.parametrize("options, error, words", [
    (dict(scenario="hybrid-120m", bogus=1), TypeError, "bogus"),
    (dict(scenario="hybrid-120m", frontend="no-such-filter"), ValueError, "no-such-filter"),
    (dict(scenario="no-such-world"), ValueError, "no-such-world"),
    (dict(scenario="hybrid-120m", frontend="rbpf", particles=-3), ValueError, "particles"),
    (dict(scenario="hybrid-120m", frontend="rbpf", particles="many"), ValueError, "particles"),
    (dict(scenario="hybrid-120m", particles=100), ValueError, "particles"),
    (dict(dataset="/no/such/data-set"), FileNotFoundError, "/no/such/data-set"),
    (dict(), ValueError, "--dataset or --scenario"),
])
def test_bad_options_raise_naming_the_keyword(options, error, words):
    with pytest.raises(error, match=words):
        subslam.run(**options)


def test_join_refuses_a_missing_file_and_a_map_that_is_not_one():
    with pytest.raises(FileNotFoundError, match="nowhere.jsonl"):
        subslam.join("/nowhere.jsonl")
    with pytest.raises(TypeError):
        subslam.join([1, 2, 3])


def test_options_lists_each_jobs_keywords_with_their_defaults():
    run = subslam.options("run")
    assert run["frontend"] == "ekfslam" and "particles" in run and "graph" not in run
    assert "graph" in subslam.options("solve")
    with pytest.raises(ValueError, match="no-such"):
        subslam.options("no-such")


def test_solve_takes_a_graph_in_memory_and_its_own_start(graphs, tmp_path):
    path = os.path.join(graphs, "victoria_park.txt")
    graph = subslam.read_graph(path, format="gtsam")
    assert graph.poses["estimates"].shape == (len(graph.poses["ids"]), 3)
    from_file = subslam.solve(path, format="gtsam", methods=["submaps"])
    in_memory = subslam.solve(graph, methods=["submaps"])
    assert from_file.report["methods"][0]["error"] == in_memory.report["methods"][0]["error"]
    # A start of one's own: the submap route's solution, solved again by Gauss-Newton from it.
    subslam.solve(graph, methods=["submaps"], out=str(tmp_path / "s"), plots=False)
    solved = subslam.read_graph(str(tmp_path / "s" / "submaps.g2o"))
    start = graph.with_estimates(poses=solved.poses["estimates"], points=solved.points["estimates"])
    polished = subslam.solve(start, methods=["gn"], initial="file")
    assert polished.report["methods"][0]["error"] <= from_file.report["methods"][0]["error"] * (1 + 1e-6)
    with pytest.raises(ValueError, match="shape"):
        graph.with_estimates(poses=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="--graph, --format and --noise"):
        subslam.solve(graph, format="g2o")


def test_join_starts_at_the_initial_pose_given():
    covariance = np.diag([0.01, 0.01, 0.001, 0.04, 0.04])
    maps = [subslam.LocalMap(0, 0.0, 1.0, [1.0, 0.0, 0.0, 3.0, 2.0], covariance)]
    joined = subslam.join(maps, initial_pose=[10.0, 5.0, np.pi / 2])
    assert np.allclose(joined.anchors.poses[0], [10.0, 5.0, np.pi / 2])
    assert np.allclose(joined.landmarks.positions[0], [8.0, 8.0])
    with pytest.raises(ValueError, match="initial_pose"):
        subslam.join(maps, initial_pose=[0.0, 0.0, 0.0], scenario="hybrid-120m")
