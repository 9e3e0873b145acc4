// joins.csv (docs/formats.md): one row per join — map_id,seconds, then how much each
// joiner counter changed over that join. Written by `subslam run` and `subslam join`.
#ifndef SUBSLAM_PIPELINE_SRC_JOINS_CSV_H_
#define SUBSLAM_PIPELINE_SRC_JOINS_CSV_H_

#include <string>
#include <vector>

#include "subslam/backend/map_joiner.h"

namespace subslam::pipeline {

std::string JoinsCsv(const std::vector<backend::JoinSummary>& joins);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_SRC_JOINS_CSV_H_
