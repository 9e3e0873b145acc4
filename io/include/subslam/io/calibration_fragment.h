// A robot's calibration as a manifest fragment: the `motion` and `sensor` keys of
// dataset.json (docs/formats.md) that `subslam calibrate` estimates, laid over a data
// set's own values — how a calibration is used in place of the manifest's first estimates.
//
// The file is calibration.json as `subslam calibrate` writes it (its "manifest_fragment"
// object), or a JSON object that is the fragment itself:
//   {"motion": {"sigma_v": …, "sigma_v_scale": …, "sigma_omega": … | "sigma_steer": …,
//               "sigma_omega_scale": … | "sigma_steer_scale": …,
//               "control_scale": [s0, s1], "control_offset": [o0, o1]},
//    "sensor": {"sigma_range": …, "sigma_bearing": …, "min_range": …, "max_range": …,
//               "fov": [min, max]}}
// Every key is optional; what is given replaces the data set's value. Bad values fail with
// the file and the field, and leave the data set unchanged.
#ifndef SUBSLAM_IO_CALIBRATION_FRAGMENT_H_
#define SUBSLAM_IO_CALIBRATION_FRAGMENT_H_

#include <string>

#include "absl/status/status.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

absl::Status ApplyCalibrationFile(const std::string& path, Dataset* dataset);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_CALIBRATION_FRAGMENT_H_
