#include "subslam/models/scan.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace subslam {

absl::Status CheckScan(const Scan& scan) {
  if (!std::isfinite(scan.t)) return absl::InvalidArgumentError(absl::StrCat("scan time is not finite: ", scan.t));
  for (size_t k = 0; k < scan.detections.size(); ++k) {
    const Detection& d = scan.detections[k];
    if (!(std::isfinite(d.range_m) && d.range_m > 0.0) || !std::isfinite(d.bearing_rad)) {
      return absl::InvalidArgumentError(absl::StrCat("scan at t = ", scan.t, " s, detection ", k, ": range ", d.range_m,
                                                     " m and bearing ", d.bearing_rad,
                                                     " rad (a finite range > 0 and a finite bearing needed)"));
    }
  }
  return absl::OkStatus();
}

}  // namespace subslam
