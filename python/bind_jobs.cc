// subslam.run, join, solve, study: the tool's jobs, with the tool's options as keywords
// (docs/cli.md without the dashes), run with the GIL released.
#include <pybind11/stl.h>

#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "bindings.h"
#include "command_flags.h"
#include "convert.h"
#include "flag_kwargs.h"
#include "graph.h"
#include "subslam/io/output_directory.h"
#include "subslam/io/submaps_jsonl.h"
#include "tool_jobs.h"

namespace py = pybind11;

namespace subslam::python {
namespace {

// kwargs without `name`, and the value it had (None when absent).
py::object Take(py::kwargs* kwargs, const char* name) {
  if (!kwargs->contains(name)) return py::none();
  py::object value = (*kwargs)[name];
  PyDict_DelItemString(kwargs->ptr(), name);
  return value;
}

py::dict RunResultDict(pipeline::RunResult r) {
  py::dict d;
  d["report"] = JsonToPython(r.report);
  d["trajectory_online"] = TrajectoryArrays(r.online);
  d["trajectory_final"] = TrajectoryArrays(r.final_trajectory);
  d["landmarks"] = LandmarkArrays(r.landmarks);
  d["local_maps"] = std::move(r.local_maps);
  if (r.stop) {
    d["stopped"] = py::dict(py::arg("cause") = pipeline::ToString(r.stop->cause), py::arg("step") = r.stop->step,
                            py::arg("t") = r.stop->t, py::arg("reason") = r.stop->reason);
  } else {
    d["stopped"] = py::none();
  }
  return d;
}

py::dict Run(py::kwargs kwargs) {
  py::object dataset = Take(&kwargs, "dataset");
  const bool in_memory = py::isinstance<io::Dataset>(dataset);
  if (!dataset.is_none() && !in_memory) kwargs["dataset"] = dataset;
  tool::RunRequest request;
  {
    FlagScope flags("run", kwargs);
    request = ValueOrThrow(tool::RunRequestFromFlags(/*input_given=*/in_memory));
    request.options.invocation = flags.Invocation();
    request.options.progress = false;
  }
  std::optional<io::Dataset> input;
  if (in_memory) input = dataset.cast<const io::Dataset&>();  // a copy: the run changes it
  pipeline::RunResult result;
  {
    py::gil_scoped_release unlocked;
    if (!in_memory) input = ValueOrThrow(tool::ReadInput(request.input));
    result = ValueOrThrow(pipeline::RunPipeline(*std::move(input), request.options));
  }
  return RunResultDict(std::move(result));
}

py::dict Join(py::kwargs kwargs) {
  py::object submaps = Take(&kwargs, "submaps");
  const bool in_memory = !submaps.is_none() && !py::isinstance<py::str>(submaps) && !py::hasattr(submaps, "__fspath__");
  if (!submaps.is_none() && !in_memory) kwargs["submaps"] = submaps;
  if (submaps.is_none()) throw py::type_error("join() needs submaps= (a submaps.jsonl path or a list of LocalMap)");
  py::object initial_pose = Take(&kwargs, "initial_pose");
  tool::JoinRequest request;
  {
    FlagScope flags("join", kwargs);
    request = ValueOrThrow(tool::JoinRequestFromFlags(/*submaps_required=*/!in_memory));
    request.options.invocation = flags.Invocation();
  }
  if (!initial_pose.is_none()) {
    if (!request.input.empty())
      throw py::value_error("join(): initial_pose and dataset= or scenario= both give the start");
    const py::array_t<double> p = CheckedArray(initial_pose, {3}, "initial_pose");
    request.options.initial_pose = Pose2(p.at(0), p.at(1), WrapAngle(p.at(2)));
  }
  std::vector<LocalSubmap> maps;
  if (in_memory) {
    try {
      maps = submaps.cast<std::vector<LocalSubmap>>();
    } catch (const py::cast_error&) {
      throw py::type_error("join(): submaps: expected a submaps.jsonl path or a list of LocalMap");
    }
  }
  pipeline::JoinResult r;
  {
    py::gil_scoped_release unlocked;
    if (!in_memory) maps = ValueOrThrow(io::ReadSubmapsJsonl(request.submaps_path));
    r = ValueOrThrow(tool::RunJoinRequest(request, maps));
  }
  py::dict d;
  d["report"] = JsonToPython(r.report);
  d["anchor_times"] = r.anchor_times;
  d["anchors"] = TrajectoryArrays(r.anchors);
  d["anchors_online"] = TrajectoryArrays(r.anchors_online);
  d["landmarks"] = LandmarkArrays(r.landmarks);
  return d;
}

py::dict Solve(py::kwargs kwargs) {
  py::object graph = Take(&kwargs, "graph");
  std::shared_ptr<Graph> in_memory;
  if (!graph.is_none()) {
    try {
      in_memory = graph.cast<std::shared_ptr<Graph>>();
    } catch (const py::cast_error&) {
      kwargs["graph"] = graph;  // a path
    }
  }
  tool::SolveRequest request;
  {
    FlagScope flags("solve", kwargs);
    request = ValueOrThrow(tool::SolveRequestFromFlags(/*graph_given=*/in_memory != nullptr));
    request.options.invocation = flags.Invocation();
  }
  pipeline::SolveResult r;
  {
    py::gil_scoped_release unlocked;
    if (in_memory != nullptr) {
      request.options.source = GraphSource(*in_memory);
      r = ValueOrThrow(pipeline::RunSolve(in_memory->graph, request.options));
    } else {
      const posegraph::PoseGraph read = ValueOrThrow(tool::ReadSolveGraph(&request));
      r = ValueOrThrow(pipeline::RunSolve(read, request.options));
    }
  }
  py::dict d;
  d["report"] = JsonToPython(r.report);
  return d;
}

py::dict Study(const std::string& name, py::kwargs kwargs) {
  tool::StudyRequest request;
  {
    FlagScope flags("study", kwargs);
    request = ValueOrThrow(tool::StudyRequestFromFlags(name));
    request.options.progress = false;
  }
  {
    py::gil_scoped_release unlocked;
    ThrowIfError(io::PrepareOutputDirectory(request.options.out_dir, "study").status());
    ThrowIfError(study::RunStudy(*request.study, request.options));
  }
  py::dict d;
  d["out"] = request.options.out_dir;
  if (request.options.shard.count == 1) {
    std::ifstream in(request.options.out_dir + "/summary.json");
    std::stringstream text;
    text << in.rdbuf();
    d["summary"] = py::module_::import("json").attr("loads")(text.str());
  }
  return d;
}

// The keywords a command takes: each flag some invocation of it reads, with its default.
py::dict Options(const std::string& command) {
  py::dict options;
  for (const std::string& name : cli::ProgramFlagNames()) {
    if (cli::CommandMayReadFlag(name, command))
      options[py::str(name)] = absl::FindCommandLineFlag(name)->DefaultValue();
  }
  if (options.empty()) throw py::value_error("options(): unknown command \"" + command + "\"");
  return options;
}

}  // namespace

void BindJobs(py::module_& m) {
  m.def("options", &Options, py::arg("command"), R"doc(
The keywords a job takes (run, join, solve, study, simulate, calibrate), each with its
default as the tool prints it; `subslam help COMMAND` says what each does.)doc");
  m.def("run", &Run, R"doc(
`subslam run` as a call: dataset= (a directory or a Dataset) or scenario= (with seed=, …),
frontend=, backend= and every other option of `subslam help run` as a keyword. Returns a
dict: report (report.json's content), trajectory_online, trajectory_final, landmarks,
local_maps, stopped (None, or why the run stopped early). out= also writes the outputs.)doc");
  m.def("join", &Join, R"doc(
`subslam join` as a call: submaps= (a submaps.jsonl path or a list of LocalMap), backend=
(default eif) and the options of `subslam help join`. Returns report, anchor_times,
anchors, anchors_online, landmarks.)doc");
  m.def("solve", &Solve, R"doc(
`subslam solve` as a call: graph= (a g2o, TORO, iSAM or GTSAM file, or a Graph), format=,
methods=, …
Returns report (each method's error, iterations, time); out= writes METHOD.g2o.)doc");
  m.def("study", &Study, py::arg("name"), R"doc(
`subslam study NAME` as a call: out= (required), trials=, workers=, methods=, shard=.
Returns out and summary (summary.json's content, for a whole study).)doc");
}

}  // namespace subslam::python
