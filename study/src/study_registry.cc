#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "studies.h"
#include "subslam/study/study.h"

namespace subslam::study {

std::vector<std::string> StudyNames() { return {"hybridslam", "combined-slam", "fmj", "iseif"}; }

absl::StatusOr<std::unique_ptr<Study>> MakeStudy(const std::string& name) {
  if (name == "hybridslam") return MakeHybridSlamStudy();
  if (name == "combined-slam") return MakeCombinedSlamStudy();
  if (name == "fmj") return MakeFmjStudy();
  if (name == "iseif") return MakeIseifStudy();
  return absl::InvalidArgumentError(
      absl::StrCat("unknown study \"", name, "\" (studies: ", absl::StrJoin(StudyNames(), ", "), ")"));
}

}  // namespace subslam::study
