#include "subslam/io/dataset.h"

#include "absl/strings/str_cat.h"
#include "subslam/models/unicycle_model.h"

namespace subslam::io {

const char* ToString(MotionModelType type) {
  switch (type) {
    case MotionModelType::kUnicycle:
      return "unicycle";
    case MotionModelType::kAckermann:
      return "ackermann";
  }
  return "unknown";
}

absl::StatusOr<MotionModelType> MotionModelTypeFromString(const std::string& name) {
  if (name == "unicycle") return MotionModelType::kUnicycle;
  if (name == "ackermann") return MotionModelType::kAckermann;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown motion model \"", name, "\" (expected unicycle or ackermann)"));
}

std::unique_ptr<models::MotionModel> MotionConfig::MakeModel() const {
  if (model == MotionModelType::kAckermann) {
    return std::make_unique<models::AckermannModel>(geometry, noise);
  }
  return std::make_unique<models::UnicycleModel>(noise);
}

size_t Dataset::NumDetections() const {
  size_t n = 0;
  for (const Scan& s : scans) n += s.detections.size();
  return n;
}

}  // namespace subslam::io
