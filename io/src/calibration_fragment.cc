#include "subslam/io/calibration_fragment.h"

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "control_correction.h"
#include "json_fields.h"
#include "subslam/io/text_table.h"

namespace subslam::io {
namespace {

using nlohmann::json;

// Sets *value from parent[key] when present: > 0 (`positive`) or ≥ 0.
absl::Status OptionalSigma(const JsonFields& f, const json& parent, const std::string& path, const std::string& key,
                           bool positive, double* value) {
  if (!parent.contains(key)) return absl::OkStatus();
  absl::StatusOr<double> d = f.Number(parent, path, key);
  if (!d.ok()) return d.status();
  if (positive ? !(*d > 0.0) : !(*d >= 0.0)) {
    return f.Error(JsonFields::Join(path, key), absl::StrCat("must be ", positive ? "> 0" : ">= 0", ", got ", *d));
  }
  *value = *d;
  return absl::OkStatus();
}

absl::Status OptionalPair(const JsonFields& f, const json& parent, const std::string& path, const std::string& key,
                          Eigen::Vector2d* value) {
  if (!parent.contains(key)) return absl::OkStatus();
  absl::StatusOr<std::vector<double>> v = f.Numbers(parent, path, key, 2);
  if (!v.ok()) return v.status();
  *value = Eigen::Vector2d((*v)[0], (*v)[1]);
  return absl::OkStatus();
}

absl::Status ApplyMotion(const JsonFields& f, const json& j, const std::string& path, MotionConfig* m) {
  const bool unicycle = m->model == MotionModelType::kUnicycle;
  const std::string ch1 = unicycle ? "sigma_omega" : "sigma_steer";
  if (absl::Status s =
          f.CheckKeys(j, path, {"sigma_v", "sigma_v_scale", ch1, ch1 + "_scale", "control_scale", "control_offset"});
      !s.ok()) {
    return s;
  }
  absl::Status s = OptionalSigma(f, j, path, "sigma_v", true, &m->noise.sigma_u0);
  if (s.ok()) s = OptionalSigma(f, j, path, "sigma_v_scale", false, &m->noise.scale_u0);
  if (s.ok()) s = OptionalSigma(f, j, path, ch1, true, &m->noise.sigma_u1);
  if (s.ok()) s = OptionalSigma(f, j, path, ch1 + "_scale", false, &m->noise.scale_u1);
  if (s.ok()) s = ParseControlCorrection(f, j, path, m);
  return s;
}

absl::Status ApplySensor(const JsonFields& f, const json& j, const std::string& path, models::RangeBearingConfig* rb) {
  if (absl::Status s = f.CheckKeys(j, path, {"sigma_range", "sigma_bearing", "min_range", "max_range", "fov"});
      !s.ok()) {
    return s;
  }
  absl::Status s = OptionalSigma(f, j, path, "sigma_range", true, &rb->sigma_range_m);
  if (s.ok()) s = OptionalSigma(f, j, path, "sigma_bearing", true, &rb->sigma_bearing_rad);
  if (s.ok()) s = OptionalSigma(f, j, path, "min_range", false, &rb->min_range_m);
  if (s.ok()) s = OptionalSigma(f, j, path, "max_range", true, &rb->max_range_m);
  Eigen::Vector2d fov(rb->fov_min_rad, rb->fov_max_rad);
  if (s.ok()) s = OptionalPair(f, j, path, "fov", &fov);
  if (!s.ok()) return s;
  rb->fov_min_rad = fov[0];
  rb->fov_max_rad = fov[1];
  if (!(rb->max_range_m > rb->min_range_m))
    return f.Error(JsonFields::Join(path, "max_range"), "must be greater than min_range");
  if (absl::Status v = rb->Validate(); !v.ok()) return f.Error(JsonFields::Join(path, "fov"), std::string(v.message()));
  return absl::OkStatus();
}

}  // namespace

absl::Status ApplyCalibrationFile(const std::string& path, Dataset* dataset) {
  absl::StatusOr<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  absl::StatusOr<json> parsed = ParseJsonDocument(path, *text);
  if (!parsed.ok()) return parsed.status();
  const json& doc = *parsed;
  const JsonFields f(path);
  if (!doc.is_object()) return f.Error("(root)", "expected a JSON object");
  const json& fragment = doc.contains("manifest_fragment") ? doc.at("manifest_fragment") : doc;
  const std::string prefix = doc.contains("manifest_fragment") ? "manifest_fragment" : "";
  if (!fragment.is_object()) return f.Error(prefix, "expected an object");
  if (absl::Status s = f.CheckKeys(fragment, prefix, {"motion", "sensor"}); !s.ok()) return s;
  Dataset updated = *dataset;
  if (fragment.contains("motion")) {
    if (!fragment.at("motion").is_object()) return f.Error(JsonFields::Join(prefix, "motion"), "expected an object");
    if (absl::Status s = ApplyMotion(f, fragment.at("motion"), JsonFields::Join(prefix, "motion"), &updated.motion);
        !s.ok())
      return s;
  }
  if (fragment.contains("sensor")) {
    if (!fragment.at("sensor").is_object()) return f.Error(JsonFields::Join(prefix, "sensor"), "expected an object");
    if (absl::Status s =
            ApplySensor(f, fragment.at("sensor"), JsonFields::Join(prefix, "sensor"), &updated.sensor.range_bearing);
        !s.ok())
      return s;
  }
  dataset->motion = updated.motion;
  dataset->sensor = updated.sensor;
  return absl::OkStatus();
}

}  // namespace subslam::io
