// subslam.Slam: the online loop a navigation stack or a simulator drives step by step.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "backend_flags.h"
#include "bindings.h"
#include "command_flags.h"
#include "convert.h"
#include "flag_errors.h"
#include "flag_kwargs.h"
#include "subslam/frontend/online_estimator.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/submap_slam.h"
#include "tool_flags.h"
#include "tool_jobs.h"

namespace py = pybind11;

namespace subslam::python {
namespace {

// Keywords that say where a job's data come from or where its outputs go: the online loop
// has its data set and writes nothing.
constexpr const char* kJobOnlyKeywords[] = {"dataset", "scenario", "calibration", "out", "progress", "quiet", "config"};

class OnlineSlam {
 public:
  OnlineSlam(std::shared_ptr<io::Dataset> dataset, const std::string& frontend, const py::object& backend,
             const py::kwargs& kwargs)
      : dataset_(std::move(dataset)) {
    for (const char* name : kJobOnlyKeywords) {
      if (kwargs.contains(name)) {
        throw py::type_error(absl::StrCat("Slam() got an unexpected keyword argument '", name,
                                          "' (the data set is its first argument; the jobs run(), join() take it)"));
      }
    }
    py::kwargs all;
    for (const auto& [key, value] : kwargs) all[key] = value;
    all["frontend"] = frontend;
    if (!backend.is_none()) {
      all["backend"] = backend;
    } else if (frontend == "rbpf" || frontend == "ekf") {
      all["backend"] = "eif";  // local maps are joined by the flagship's back-end unless told otherwise
    }
    pipeline::RunOptions options;
    {
      FlagScope flags("run", all);
      auto kind = pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
      if (!kind.ok()) throw py::value_error(absl::StrCat("frontend: ", kind.status().message()));
      auto joiner = pipeline::BackendFromString(absl::GetFlag(FLAGS_backend));
      if (!joiner.ok()) throw py::value_error(absl::StrCat("backend: ", joiner.status().message()));
      cli::CommandContext context{.command = "run", .frontend = *kind};
      if (*kind == pipeline::Frontend::kRbpf || *kind == pipeline::Frontend::kEkfLocal) context.backend = *joiner;
      ThrowIfError(cli::CheckFlagsRead(context));
      ThrowIfError(cli::CheckNamingFlags([&] { return tool::RunOptionsFromFlags(*kind).status(); }));
      options = *tool::RunOptionsFromFlags(*kind);
    }
    sensor_yaw_ = options.noise.sensor_yaw;
    estimator_ = ValueOrThrow(pipeline::MakeOnlineEstimator(*dataset_, options));
    if (!dataset_->controls.empty()) time_ = dataset_->controls.front().t;
    chain_ = dynamic_cast<pipeline::SubmapSlam*>(estimator_.get());
  }

  void Predict(const Eigen::Vector2d& u, double dt) {
    if (!(dt >= 0.0) || !u.allFinite()) throw py::value_error("predict: u must be finite and dt >= 0");
    CheckOpen();
    time_ += dt;
    py::gil_scoped_release unlocked;
    estimator_->Predict(u, dt);
  }

  void Update(const py::handle& ranges, const py::handle& bearings, const py::handle& signatures,
              const py::handle& truth_ids, const std::optional<double>& t) {
    CheckOpen();
    if (t.has_value() && !std::isfinite(*t)) throw py::value_error("update: t must be finite");
    const py::array_t<double> r = CheckedArray(ranges, {-1}, "ranges");
    const long n = static_cast<long>(r.shape(0));
    const py::array_t<double> b = CheckedArray(bearings, {n}, "bearings");
    Scan scan;
    scan.t = t.value_or(time_);
    scan.detections.resize(n);
    for (long i = 0; i < n; ++i) {
      scan.detections[i].range_m = r.at(i);
      scan.detections[i].bearing_rad = sensor_yaw_ ? WrapAngle(b.at(i) + *sensor_yaw_) : b.at(i);
    }
    if (!signatures.is_none()) {
      const py::array_t<double> s = CheckedArray(signatures, {n}, "signatures");
      for (long i = 0; i < n; ++i) scan.detections[i].signature = s.at(i);
    }
    if (!truth_ids.is_none()) {
      const py::array_t<double> ids = CheckedArray(truth_ids, {n}, "truth_ids");
      for (long i = 0; i < n; ++i) scan.detections[i].truth_id = static_cast<int>(ids.at(i));
    }
    absl::Status updated;
    {
      py::gil_scoped_release unlocked;
      updated = estimator_->Update(scan);
    }
    ThrowIfError(updated);
  }

  void RecordStep(double t) {
    if (chain_ != nullptr) chain_->RecordStep(t);
  }

  void Finish() {
    CheckOpen();
    finished_ = true;
    if (chain_ == nullptr) return;
    py::gil_scoped_release unlocked;
    ThrowIfError(chain_->Finish());
  }

  py::dict FinalTrajectory() const {
    if (chain_ == nullptr) throw py::value_error("final_trajectory: a single-map filter has no anchors to re-express");
    if (!finished_) throw py::value_error("final_trajectory: call finish() first");
    return TrajectoryArrays(chain_->FinalTrajectory());
  }

  std::vector<LocalSubmap> LocalMaps() const {
    std::vector<LocalSubmap> maps;
    if (chain_ != nullptr) {
      for (const frontend::ClosedLocalMap& c : chain_->local_maps()) maps.push_back(c.submap);
    }
    return maps;
  }

  const frontend::OnlineEstimator& estimator() const { return *estimator_; }

 private:
  void CheckOpen() const {
    if (finished_) throw py::value_error("the run is finished: make a new Slam to go on");
  }

  std::shared_ptr<io::Dataset> dataset_;  // its models are the estimator's
  std::unique_ptr<frontend::OnlineEstimator> estimator_;
  pipeline::SubmapSlam* chain_ = nullptr;  // the local-map front-ends' pipeline
  std::optional<double> sensor_yaw_;
  double time_ = 0.0;  // the data set's start plus every predict's dt: a scan's time unless given
  bool finished_ = false;
};

}  // namespace

void BindOnline(py::module_& m) {
  py::class_<OnlineSlam>(m, "Slam", R"doc(
The online estimator, driven step by step: predict with each control, update with each
scan, read the pose. The models and the initial pose are the data set's; the estimator is
any front-end by name (rbpf, ekf: local maps joined by `backend`; ekfslam, fastslam, seif,
iseif, odometry: single-map filters) with the options of `subslam run` as keywords
(particles=200, known_association=True, …; `subslam help run`).)doc")
      .def(py::init<std::shared_ptr<io::Dataset>, const std::string&, const py::object&, const py::kwargs&>(),
           py::arg("dataset"), py::arg("frontend") = "rbpf", py::arg("backend") = py::none(),
           "backend: for rbpf and ekf, eif unless given (none: local maps chained, not joined)")
      .def("predict", &OnlineSlam::Predict, py::arg("u"), py::arg("dt"),
           "Moves the estimate over dt [s] with the control u (v [m/s], ω [rad/s] or steer [rad]) held over it.")
      .def("update", &OnlineSlam::Update, py::arg("ranges"), py::arg("bearings"), py::arg("signatures") = py::none(),
           py::arg("truth_ids") = py::none(), py::arg("t") = py::none(),
           "Updates with a scan: ranges [m] and bearings [rad] in the vehicle frame, the signatures when the "
           "sensor has them, the true ids only for known association; t [s] (default: the data set's start plus "
           "the predictions' dt).")
      .def("record_step", &OnlineSlam::RecordStep, py::arg("t"),
           "Remembers the step (local-map front-ends) for final_trajectory().")
      .def("finish", &OnlineSlam::Finish, "Closes and joins the open local map.")
      .def_property_readonly("name", [](const OnlineSlam& s) { return s.estimator().Name(); })
      .def_property_readonly(
          "pose", [](const OnlineSlam& s) { return s.estimator().pose().vector(); }, "(x, y, θ) in the world frame")
      .def_property_readonly("pose_covariance", [](const OnlineSlam& s) { return s.estimator().pose_covariance(); })
      .def(
          "landmarks", [](const OnlineSlam& s) { return LandmarkArrays(s.estimator().Map()); },
          "The map: {'ids', 'positions' (N, 2), 'covariances' (N, 2, 2)}.")
      .def("final_trajectory", &OnlineSlam::FinalTrajectory,
           "Every recorded step re-expressed with the final anchors (after finish()).")
      .def("local_maps", &OnlineSlam::LocalMaps, "The closed local maps (LocalMap objects).")
      .def("counters", [](const OnlineSlam& s) { return s.estimator().Counters(); });
}

}  // namespace subslam::python
