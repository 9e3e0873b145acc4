// Reading a study's runs.csv back into groups of runs and their statistics.
#ifndef SUBSLAM_STUDY_SRC_TABLE_STATISTICS_H_
#define SUBSLAM_STUDY_SRC_TABLE_STATISTICS_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/study/run_table.h"

namespace subslam::study {

// The rows of `runs` whose column values equal `key` (column name → text).
std::vector<int> RowsWhere(const RunTable& runs, const std::vector<std::pair<std::string, std::string>>& key);

// A column's values over some rows (an error if one is not a number).
absl::StatusOr<std::vector<double>> Values(const RunTable& runs, const std::vector<int>& rows,
                                           const std::string& column);

double Median(std::vector<double> values);  // NaN when empty; NaNs are left out
double Sum(const std::vector<double>& values);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_SRC_TABLE_STATISTICS_H_
