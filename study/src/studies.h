// The studies StudyNames() lists, one file each.
#ifndef SUBSLAM_STUDY_SRC_STUDIES_H_
#define SUBSLAM_STUDY_SRC_STUDIES_H_

#include <memory>

#include "subslam/study/study.h"

namespace subslam::study {

std::unique_ptr<Study> MakeHybridSlamStudy();    // hybridslam_study.cc
std::unique_ptr<Study> MakeCombinedSlamStudy();  // combined_slam_study.cc
std::unique_ptr<Study> MakeFmjStudy();           // fmj_study.cc
std::unique_ptr<Study> MakeIseifStudy();         // iseif_study.cc

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_SRC_STUDIES_H_
