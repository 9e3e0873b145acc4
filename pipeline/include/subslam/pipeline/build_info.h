// What build of subslam is running: recorded in every report so that a result can be
// traced to the code that produced it, and printed by `subslam --version`.
#ifndef SUBSLAM_PIPELINE_BUILD_INFO_H_
#define SUBSLAM_PIPELINE_BUILD_INFO_H_

namespace subslam::pipeline {

// The project's version (CMake's project version, "MAJOR.MINOR.PATCH").
const char* Version();

// The git commit the library was built from, "<40 hex digits>" with "-dirty" appended
// when the work tree had uncommitted changes, or "unknown" outside a git checkout.
const char* Commit();

// CMake's build type (Release, Debug, RelWithDebInfo, …; "unspecified" when none).
const char* BuildType();

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_BUILD_INFO_H_
