"""subslam: submap-based landmark SLAM from Python (docs/python.md).

    import subslam
    dataset = subslam.read_dataset("../shared/data/victoria_park")
    result = subslam.run(dataset=dataset, frontend="rbpf", backend="eif")
    result.landmarks.positions        # (N, 2) [m], world frame
    result.report["metrics"]          # report.json's content

Units are metres, radians and seconds; poses are (x, y, θ) rows. The jobs take the options
of the `subslam` command of the same name as keywords (`subslam help run`, docs/cli.md),
named without their dashes; a keyword the job would not read, or a value out of range,
raises TypeError or ValueError naming it. Long calls release the GIL.
"""
from typing import NamedTuple

from ._subslam import (Dataset, Graph, LocalMap, Slam, __version__, options, read_dataset, read_graph,
                       read_local_maps, scenarios, simulate, write_local_maps)
from . import _subslam

__all__ = ["Dataset", "Graph", "LocalMap", "Slam", "Trajectory", "Landmarks", "RunResult", "JoinResult", "SolveResult",
           "StudyResult", "options", "read_dataset", "read_graph", "read_local_maps", "write_local_maps", "simulate", "scenarios", "run",
           "join", "solve", "study", "__version__"]


class Trajectory(NamedTuple):
    """Poses over time: t (N,) [s], poses (N, 3) (x, y, θ), covariances (N, 3, 3)."""
    t: "numpy.ndarray"
    poses: "numpy.ndarray"
    covariances: "numpy.ndarray"


class Landmarks(NamedTuple):
    """A map: ids (N,), positions (N, 2) [m], covariances (N, 2, 2)."""
    ids: "numpy.ndarray"
    positions: "numpy.ndarray"
    covariances: "numpy.ndarray"


class RunResult(NamedTuple):
    """What `subslam run` writes: report.json's content, the trajectories, the map, the local maps;
    stopped is None, or a dict saying why and where the run stopped early (health.stopped)."""
    report: dict
    trajectory_online: Trajectory
    trajectory_final: Trajectory
    landmarks: Landmarks
    local_maps: list
    stopped: object


class JoinResult(NamedTuple):
    """What `subslam join` writes: report.json's content, the anchors (final and as each join left
    them; row k = the start of local map k) and the global map."""
    report: dict
    anchors: Trajectory
    anchors_online: Trajectory
    landmarks: Landmarks


class SolveResult(NamedTuple):
    """What `subslam solve` reports: report.json's content (each method's error, iterations, time)."""
    report: dict


class StudyResult(NamedTuple):
    """A study's output directory and its summary.json (None for one slice of a sharded study)."""
    out: str
    summary: object


def run(**options) -> RunResult:
    """`subslam run`: dataset= (a directory or a Dataset) or scenario= (with seed=, …), frontend=,
    backend= and the other options of `subslam help run`; out= also writes the run's files."""
    r = _subslam.run(**options)
    return RunResult(r["report"], Trajectory(**r["trajectory_online"]), Trajectory(**r["trajectory_final"]),
                     Landmarks(**r["landmarks"]), r["local_maps"], r["stopped"])


def join(submaps, backend="eif", **options) -> JoinResult:
    """`subslam join`: submaps is a submaps.jsonl path or a list of LocalMap; backend (eif,
    ceres, ekf, tree-ekf, tree-eif, tree-ceres); the first map's anchor from dataset= or
    scenario= (with the truth) or initial_pose=(x, y, θ) (default: the origin); and the
    options of `subslam help join`."""
    r = _subslam.join(submaps=submaps, backend=backend, **options)
    return JoinResult(r["report"], Trajectory(**r["anchors"]), Trajectory(**r["anchors_online"]),
                      Landmarks(**r["landmarks"]))


def solve(graph, **options) -> SolveResult:
    """`subslam solve`: graph is a g2o, TORO, iSAM or GTSAM file (format=, noise= say how to read
    it) or a Graph (read_graph); methods=, initial=, max_iterations=, …"""
    if hasattr(graph, "__fspath__"):
        graph = str(graph)
    return SolveResult(_subslam.solve(graph=graph, **options)["report"])


def study(name, **options) -> StudyResult:
    """`subslam study NAME`: out= (required), trials=, workers=, methods=, shard=."""
    r = _subslam.study(name, **options)
    return StudyResult(r["out"], r.get("summary"))
