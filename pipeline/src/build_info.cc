#include "subslam/pipeline/build_info.h"

#include "build_info_commit.h"  // generated at every build: SUBSLAM_COMMIT

namespace subslam::pipeline {

const char* Version() { return SUBSLAM_VERSION; }
const char* Commit() { return SUBSLAM_COMMIT; }
const char* BuildType() { return SUBSLAM_BUILD_TYPE; }

}  // namespace subslam::pipeline
