// The odometry correction of a manifest's `motion` object (io::MotionConfig::Corrected):
// `control_scale` (both > 0) and `control_offset`, two numbers each, optional. Read by the
// data-set reader and by a calibration fragment. Private to subslam::io.
#ifndef SUBSLAM_IO_SRC_CONTROL_CORRECTION_H_
#define SUBSLAM_IO_SRC_CONTROL_CORRECTION_H_

#include <string>
#include <vector>

#include "json_fields.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

// Sets what `motion` (at `path`) gives; on an error names the field and leaves *m as it was.
inline absl::Status ParseControlCorrection(const JsonFields& f, const nlohmann::json& motion, const std::string& path,
                                           MotionConfig* m) {
  Eigen::Vector2d scale = m->control_scale, offset = m->control_offset;
  if (motion.contains("control_scale")) {
    absl::StatusOr<std::vector<double>> v = f.Numbers(motion, path, "control_scale", 2);
    if (!v.ok()) return v.status();
    if (!((*v)[0] > 0.0 && (*v)[1] > 0.0))
      return f.Error(JsonFields::Join(path, "control_scale"), "both scales must be > 0");
    scale = Eigen::Vector2d((*v)[0], (*v)[1]);
  }
  if (motion.contains("control_offset")) {
    absl::StatusOr<std::vector<double>> v = f.Numbers(motion, path, "control_offset", 2);
    if (!v.ok()) return v.status();
    offset = Eigen::Vector2d((*v)[0], (*v)[1]);
  }
  m->control_scale = scale;
  m->control_offset = offset;
  return absl::OkStatus();
}

}  // namespace subslam::io

#endif  // SUBSLAM_IO_SRC_CONTROL_CORRECTION_H_
