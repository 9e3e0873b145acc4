#include "table_statistics.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace subslam::study {

std::vector<int> RowsWhere(const RunTable& runs, const std::vector<std::pair<std::string, std::string>>& key) {
  std::vector<int> columns;
  for (const auto& [name, value] : key) columns.push_back(runs.Column(name).value_or(-1));
  std::vector<int> rows;
  for (int r = 0; r < runs.num_rows(); ++r) {
    bool match = true;
    for (size_t k = 0; k < key.size() && match; ++k) {
      match = columns[k] >= 0 && runs.rows()[r][columns[k]] == key[k].second;
    }
    if (match) rows.push_back(r);
  }
  return rows;
}

absl::StatusOr<std::vector<double>> Values(const RunTable& runs, const std::vector<int>& rows,
                                           const std::string& column) {
  std::vector<double> values;
  for (int r : rows) {
    absl::StatusOr<double> v = runs.Number(r, column);
    if (!v.ok()) return v.status();
    values.push_back(*v);
  }
  return values;
}

double Median(std::vector<double> values) {
  std::erase_if(values, [](double v) { return std::isnan(v); });
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double Sum(const std::vector<double>& values) { return std::accumulate(values.begin(), values.end(), 0.0); }

}  // namespace subslam::study
