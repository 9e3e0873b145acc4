#include "subslam/io/dataset.h"

#include "absl/strings/str_cat.h"
#include "subslam/core/enum_names.h"
#include "subslam/models/unicycle_model.h"

namespace subslam::io {

namespace {
constexpr EnumName<MotionModelType> kMotionModelNames[] = {{MotionModelType::kUnicycle, "unicycle"},
                                                           {MotionModelType::kAckermann, "ackermann"}};
}  // namespace

const char* ToString(MotionModelType type) { return NameOf(kMotionModelNames, type); }

absl::StatusOr<MotionModelType> MotionModelTypeFromString(const std::string& name) {
  return ParseEnum(kMotionModelNames, name, "motion model");
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
