#include "subslam/io/dataset_reader.h"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "control_correction.h"
#include "json_fields.h"
#include "subslam/io/text_table.h"

namespace subslam::io {
namespace {

using nlohmann::json;

// Typed access to manifest fields (json_fields.h) plus the manifest's own kinds.
class Manifest : public JsonFields {
 public:
  explicit Manifest(std::string file) : JsonFields(std::move(file)) {}

  absl::StatusOr<const json*> Object(const json& parent, const std::string& path, const std::string& key) const {
    const std::string field = Join(path, key);
    if (!parent.contains(key)) return Error(field, "missing");
    const json& v = parent.at(key);
    if (!v.is_object()) return Error(field, "expected an object");
    return &v;
  }

  absl::StatusOr<std::string> String(const json& parent, const std::string& path, const std::string& key) const {
    const std::string field = Join(path, key);
    if (!parent.contains(key)) return Error(field, "missing");
    const json& v = parent.at(key);
    if (!v.is_string()) return Error(field, absl::StrCat("expected a string, got ", v.dump()));
    return v.get<std::string>();
  }

  absl::StatusOr<double> PositiveSigma(const json& parent, const std::string& path, const std::string& key) const {
    absl::StatusOr<double> d = Number(parent, path, key);
    if (!d.ok()) return d.status();
    if (*d <= 0.0) return Error(Join(path, key), absl::StrCat("must be > 0, got ", *d));
    return *d;
  }

  absl::StatusOr<double> NonNegative(const json& parent, const std::string& path, const std::string& key,
                                     double fallback) const {
    absl::StatusOr<double> d = Number(parent, path, key, fallback);
    if (!d.ok()) return d.status();
    if (*d < 0.0) return Error(Join(path, key), absl::StrCat("must be >= 0, got ", *d));
    return *d;
  }

  // An optional file name: absent or null → empty string.
  absl::StatusOr<std::string> OptionalFile(const json& parent, const std::string& path, const std::string& key) const {
    if (!parent.contains(key) || parent.at(key).is_null()) return std::string();
    return String(parent, path, key);
  }

  // An optional 1-based column index ≥ min_column: absent or null → 0.
  absl::StatusOr<int> OptionalColumn(const json& parent, const std::string& path, const std::string& key,
                                     int min_column) const {
    if (!parent.contains(key) || parent.at(key).is_null()) return 0;
    const json& v = parent.at(key);
    if (!v.is_number_integer() || v.get<int>() < min_column || v.get<int>() > 64) {
      return Error(Join(path, key),
                   absl::StrCat("expected null or an integer column in [", min_column, ", 64], got ", v.dump()));
    }
    return v.get<int>();
  }
};

#define SUBSLAM_CONCAT_INNER(a, b) a##b
#define SUBSLAM_CONCAT(a, b) SUBSLAM_CONCAT_INNER(a, b)
#define SUBSLAM_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                  \
  if (!tmp.ok()) return tmp.status();                 \
  lhs = *std::move(tmp)
// Assigns the value of a StatusOr expression to lhs, or returns its error.
#define SUBSLAM_ASSIGN_OR_RETURN(lhs, expr) \
  SUBSLAM_ASSIGN_OR_RETURN_IMPL(SUBSLAM_CONCAT(status_or_, __LINE__), lhs, expr)

absl::Status ParseMotion(const Manifest& m, const json& j, MotionConfig* motion, std::string* controls_file) {
  std::string model_name;
  SUBSLAM_ASSIGN_OR_RETURN(model_name, m.String(j, "motion", "model"));
  auto model = MotionModelTypeFromString(model_name);
  if (!model.ok()) return m.Error("motion.model", std::string(model.status().message()));
  motion->model = *model;
  SUBSLAM_ASSIGN_OR_RETURN(*controls_file, m.String(j, "motion", "controls_file"));
  SUBSLAM_ASSIGN_OR_RETURN(motion->noise.sigma_u0, m.PositiveSigma(j, "motion", "sigma_v"));
  SUBSLAM_ASSIGN_OR_RETURN(motion->noise.scale_u0, m.NonNegative(j, "motion", "sigma_v_scale", 0.0));
  if (absl::Status s = ParseControlCorrection(m, j, "motion", motion); !s.ok()) return s;
  const std::set<std::string> common = {"model",         "controls_file", "sigma_v",
                                        "sigma_v_scale", "control_scale", "control_offset"};
  if (motion->model == MotionModelType::kUnicycle) {
    SUBSLAM_ASSIGN_OR_RETURN(motion->noise.sigma_u1, m.PositiveSigma(j, "motion", "sigma_omega"));
    SUBSLAM_ASSIGN_OR_RETURN(motion->noise.scale_u1, m.NonNegative(j, "motion", "sigma_omega_scale", 0.0));
    std::set<std::string> allowed = common;
    allowed.insert({"sigma_omega", "sigma_omega_scale"});
    return m.CheckKeys(j, "motion", allowed);
  }
  SUBSLAM_ASSIGN_OR_RETURN(motion->noise.sigma_u1, m.PositiveSigma(j, "motion", "sigma_steer"));
  SUBSLAM_ASSIGN_OR_RETURN(motion->noise.scale_u1, m.NonNegative(j, "motion", "sigma_steer_scale", 0.0));
  SUBSLAM_ASSIGN_OR_RETURN(motion->geometry.wheelbase_m, m.Number(j, "motion", "wheelbase"));
  if (motion->geometry.wheelbase_m <= 0.0) return m.Error("motion.wheelbase", "must be > 0");
  SUBSLAM_ASSIGN_OR_RETURN(motion->geometry.encoder_offset_m, m.Number(j, "motion", "encoder_offset", 0.0));
  std::vector<double> offset = {0.0, 0.0};
  if (j.contains("sensor_offset")) {
    SUBSLAM_ASSIGN_OR_RETURN(offset, m.Numbers(j, "motion", "sensor_offset", 2));
  }
  motion->geometry.sensor_forward_m = offset[0];
  motion->geometry.sensor_left_m = offset[1];
  std::set<std::string> allowed = common;
  allowed.insert({"sigma_steer", "sigma_steer_scale", "wheelbase", "encoder_offset", "sensor_offset"});
  return m.CheckKeys(j, "motion", allowed);
}

struct SensorFiles {
  std::string observations;
  int signature_column = 0;
  int truth_id_column = 0;
  double bearing_offset = 0.0;
};

absl::Status ParseSensor(const Manifest& m, const json& j, SensorConfig* sensor, SensorFiles* files) {
  std::string type;
  SUBSLAM_ASSIGN_OR_RETURN(type, m.String(j, "sensor", "type"));
  if (type != "range_bearing") {
    return m.Error("sensor.type", absl::StrCat("unsupported sensor type \"", type, "\" (expected range_bearing)"));
  }
  SUBSLAM_ASSIGN_OR_RETURN(files->observations, m.String(j, "sensor", "observations_file"));
  SUBSLAM_ASSIGN_OR_RETURN(files->bearing_offset, m.Number(j, "sensor", "bearing_offset", 0.0));
  SUBSLAM_ASSIGN_OR_RETURN(files->signature_column, m.OptionalColumn(j, "sensor", "signature_column", 4));
  SUBSLAM_ASSIGN_OR_RETURN(files->truth_id_column, m.OptionalColumn(j, "sensor", "truth_id_column", 4));
  if (files->signature_column != 0 && files->signature_column == files->truth_id_column) {
    return m.Error("sensor.truth_id_column", "must differ from signature_column");
  }
  models::RangeBearingConfig& rb = sensor->range_bearing;
  SUBSLAM_ASSIGN_OR_RETURN(rb.sigma_range_m, m.PositiveSigma(j, "sensor", "sigma_range"));
  SUBSLAM_ASSIGN_OR_RETURN(rb.sigma_bearing_rad, m.PositiveSigma(j, "sensor", "sigma_bearing"));
  SUBSLAM_ASSIGN_OR_RETURN(rb.min_range_m, m.NonNegative(j, "sensor", "min_range", 0.0));
  SUBSLAM_ASSIGN_OR_RETURN(rb.max_range_m, m.Number(j, "sensor", "max_range"));
  if (rb.max_range_m <= rb.min_range_m) {
    return m.Error("sensor.max_range", "must be greater than sensor.min_range");
  }
  std::vector<double> fov = {-kPi, kPi};
  if (j.contains("fov")) {
    SUBSLAM_ASSIGN_OR_RETURN(fov, m.Numbers(j, "sensor", "fov", 2));
  }
  rb.fov_min_rad = fov[0];
  rb.fov_max_rad = fov[1];
  if (absl::Status s = rb.Validate(); !s.ok()) return m.Error("sensor.fov", std::string(s.message()));
  sensor->has_signature = files->signature_column != 0;
  sensor->has_truth_id = files->truth_id_column != 0;
  return m.CheckKeys(j, "sensor",
                     {"type", "observations_file", "bearing_offset", "signature_column", "truth_id_column",
                      "sigma_range", "sigma_bearing", "min_range", "max_range", "fov"});
}

// One text file of the data set, read through `read`.
absl::StatusOr<std::vector<TextRow>> Table(const FileReader& read, const std::string& path,
                                           const std::vector<std::string>& columns, int max_columns,
                                           bool allow_empty = false) {
  absl::StatusOr<std::string> text = read(path);
  if (!text.ok()) return text.status();
  return ParseTextTable(*text, path, columns, max_columns, allow_empty);
}

absl::Status NotBackwards(const std::string& path, int line, double t, double t_prev, bool strictly) {
  if (t < t_prev || (strictly && t == t_prev)) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ":", line, ": field 't' goes backwards in time (", t, " after ", t_prev, ")"));
  }
  return absl::OkStatus();
}

absl::Status ReadControls(const FileReader& read, const std::string& path, Dataset* d) {
  const bool unicycle = d->motion.model == MotionModelType::kUnicycle;
  auto rows = Table(read, path, {"t", "v", unicycle ? "omega" : "steer"}, 3);
  if (!rows.ok()) return rows.status();
  double t_prev = -INFINITY;
  for (const TextRow& r : *rows) {
    if (absl::Status s = NotBackwards(path, r.line, r.values[0], t_prev, false); !s.ok()) return s;
    if (!unicycle && std::abs(r.values[2]) >= kPi / 2) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", r.line, ": field 'steer' outside (-pi/2, pi/2): ", r.values[2]));
    }
    if (!d->controls.empty() && d->controls.back().t == r.values[0]) {
      d->controls.back().u = {r.values[1], r.values[2]};  // the later line wins
      ++d->duplicate_control_times;
    } else {
      d->controls.push_back({r.values[0], {r.values[1], r.values[2]}});
    }
    t_prev = r.values[0];
  }
  return absl::OkStatus();
}

absl::Status ReadObservations(const FileReader& read, const std::string& path, const SensorFiles& files, Dataset* d) {
  std::vector<std::string> columns = {"t", "range", "bearing"};
  const int needed = std::max({3, files.signature_column, files.truth_id_column});
  for (int c = 4; c <= needed; ++c) {
    columns.push_back(c == files.signature_column  ? "signature"
                      : c == files.truth_id_column ? "truth_id"
                                                   : absl::StrCat("column ", c));
  }
  auto rows = Table(read, path, columns, 0, /*allow_empty=*/true);
  if (!rows.ok()) return rows.status();
  double t_prev = -INFINITY;
  for (const TextRow& r : *rows) {
    const double t = r.values[0];
    if (absl::Status s = NotBackwards(path, r.line, t, t_prev, false); !s.ok()) return s;
    Detection det;
    det.range_m = r.values[1];
    if (det.range_m <= 0.0) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", r.line, ": field 'range' must be > 0, got ", det.range_m));
    }
    det.bearing_rad = WrapAngle(r.values[2] + files.bearing_offset);
    if (files.signature_column != 0) det.signature = r.values[files.signature_column - 1];
    if (files.truth_id_column != 0) {
      const double id = r.values[files.truth_id_column - 1];
      if (id != std::floor(id) || id < kFalseAlarmId || id > 1e9) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ":", r.line, ": field 'truth_id' must be an integer >= -1, got ", id));
      }
      det.truth_id = static_cast<int>(id);
    }
    if (d->scans.empty() || d->scans.back().t != t) d->scans.push_back({t, {}});
    d->scans.back().detections.push_back(det);
    t_prev = t;
  }
  return absl::OkStatus();
}

absl::Status ReadGroundTruth(const FileReader& read, const std::string& dir, const Manifest& m, const json& j,
                             Dataset* d) {
  std::string gps_file, poses_file, landmarks_file;
  SUBSLAM_ASSIGN_OR_RETURN(gps_file, m.OptionalFile(j, "ground_truth", "gps_file"));
  SUBSLAM_ASSIGN_OR_RETURN(poses_file, m.OptionalFile(j, "ground_truth", "poses_file"));
  SUBSLAM_ASSIGN_OR_RETURN(landmarks_file, m.OptionalFile(j, "ground_truth", "landmarks_file"));
  if (absl::Status s = m.CheckKeys(j, "ground_truth", {"gps_file", "poses_file", "landmarks_file"}); !s.ok()) {
    return s;
  }
  if (!gps_file.empty()) {
    const std::string path = (std::filesystem::path(dir) / gps_file).string();
    auto rows = Table(read, path, {"t", "x", "y"}, 3);
    if (!rows.ok()) return rows.status();
    double t_prev = -INFINITY;
    for (const auto& r : *rows) {
      if (absl::Status s = NotBackwards(path, r.line, r.values[0], t_prev, false); !s.ok()) return s;
      d->gps.push_back({r.values[0], {r.values[1], r.values[2]}});
      t_prev = r.values[0];
    }
  }
  if (!poses_file.empty()) {
    const std::string path = (std::filesystem::path(dir) / poses_file).string();
    auto rows = Table(read, path, {"t", "x", "y", "theta"}, 4);
    if (!rows.ok()) return rows.status();
    double t_prev = -INFINITY;
    for (const auto& r : *rows) {
      if (absl::Status s = NotBackwards(path, r.line, r.values[0], t_prev, true); !s.ok()) return s;
      d->truth_poses.push_back({r.values[0], Pose2(r.values[1], r.values[2], WrapAngle(r.values[3]))});
      t_prev = r.values[0];
    }
  }
  if (!landmarks_file.empty()) {
    const std::string path = (std::filesystem::path(dir) / landmarks_file).string();
    auto rows = Table(read, path, {"id", "x", "y"}, 3);
    if (!rows.ok()) return rows.status();
    std::set<int> seen;
    for (const auto& r : *rows) {
      const double id = r.values[0];
      if (id != std::floor(id) || id < 0 || id > 1e9 || !seen.insert(static_cast<int>(id)).second) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ":", r.line, ": field 'id' must be a unique integer >= 0, got ", id));
      }
      d->truth_landmarks.push_back({static_cast<int>(id), {r.values[1], r.values[2]}});
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<Dataset> ReadDataset(const std::string& directory) { return ReadDataset(directory, ReadFileToString); }

absl::StatusOr<Dataset> ReadDataset(const std::string& directory, const FileReader& read) {
  // The manifest's own path names its directory too.
  std::filesystem::path dir(directory);
  if (dir.filename() == "dataset.json") dir = dir.parent_path();
  const std::string manifest_path = (dir / "dataset.json").string();
  auto text = read(manifest_path);
  if (!text.ok()) return text.status();
  absl::StatusOr<json> parsed = ParseJsonDocument(manifest_path, *text);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  const Manifest m(manifest_path);
  if (!j.is_object()) return m.Error("(root)", "expected a JSON object");
  if (absl::Status s = m.CheckKeys(
          j, "", {"format", "name", "description", "initial_pose", "motion", "sensor", "ground_truth", "simulation"});
      !s.ok()) {
    return s;
  }
  std::string format;
  SUBSLAM_ASSIGN_OR_RETURN(format, m.String(j, "", "format"));
  if (format != "subslam-dataset/1") {
    return m.Error("format", absl::StrCat("unsupported format \"", format, "\" (expected subslam-dataset/1)"));
  }
  Dataset d;
  d.directory = dir.string();
  SUBSLAM_ASSIGN_OR_RETURN(d.name, m.String(j, "", "name"));
  std::vector<double> initial = {0, 0, 0};
  if (j.contains("initial_pose")) {
    SUBSLAM_ASSIGN_OR_RETURN(initial, m.Numbers(j, "", "initial_pose", 3));
  }
  d.initial_pose = Pose2(initial[0], initial[1], WrapAngle(initial[2]));

  const json* motion = nullptr;
  SUBSLAM_ASSIGN_OR_RETURN(motion, m.Object(j, "", "motion"));
  std::string controls_file;
  if (absl::Status s = ParseMotion(m, *motion, &d.motion, &controls_file); !s.ok()) return s;
  const json* sensor = nullptr;
  SUBSLAM_ASSIGN_OR_RETURN(sensor, m.Object(j, "", "sensor"));
  SensorFiles files;
  if (absl::Status s = ParseSensor(m, *sensor, &d.sensor, &files); !s.ok()) return s;

  if (absl::Status s = ReadControls(read, (dir / controls_file).string(), &d); !s.ok()) return s;
  if (absl::Status s = ReadObservations(read, (dir / files.observations).string(), files, &d); !s.ok()) {
    return s;
  }
  if (j.contains("ground_truth") && !j.at("ground_truth").is_null()) {
    const json* truth = nullptr;
    SUBSLAM_ASSIGN_OR_RETURN(truth, m.Object(j, "", "ground_truth"));
    if (absl::Status s = ReadGroundTruth(read, dir.string(), m, *truth, &d); !s.ok()) return s;
  }
  return d;
}

}  // namespace subslam::io
