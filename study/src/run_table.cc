#include "subslam/study/run_table.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"

namespace subslam::study {

RunTable::RunTable(std::vector<std::string> columns) : columns_(std::move(columns)) {}

absl::StatusOr<int> RunTable::Column(const std::string& name) const {
  for (size_t i = 0; i < columns_.size(); ++i) {
    if (columns_[i] == name) return static_cast<int>(i);
  }
  return absl::NotFoundError(absl::StrCat("no column \"", name, "\" (columns: ", absl::StrJoin(columns_, ","), ")"));
}

absl::Status RunTable::Add(std::vector<std::string> row) {
  if (row.size() != columns_.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("a row of ", row.size(), " values for ", columns_.size(), " columns"));
  }
  for (size_t i = 0; i < row.size(); ++i) {
    if (row[i].find_first_of(",\n\r") != std::string::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat("column ", columns_[i], ": value \"", row[i], "\" holds a comma or a line break"));
    }
  }
  rows_.push_back(std::move(row));
  return absl::OkStatus();
}

absl::StatusOr<std::string> RunTable::Text(int row, const std::string& name) const {
  absl::StatusOr<int> column = Column(name);
  if (!column.ok()) return column.status();
  if (row < 0 || row >= num_rows()) return absl::OutOfRangeError(absl::StrCat("no row ", row));
  return rows_[row][*column];
}

absl::StatusOr<double> RunTable::Number(int row, const std::string& name) const {
  absl::StatusOr<std::string> text = Text(row, name);
  if (!text.ok()) return text.status();
  if (*text == "nan") return std::nan("");
  double value = 0.0;
  if (!absl::SimpleAtod(*text, &value)) {
    return absl::InvalidArgumentError(
        absl::StrCat("row ", row + 1, ", column ", name, ": \"", *text, "\" is not a number"));
  }
  return value;
}

absl::Status RunTable::SortBy(const std::string& name) {
  absl::StatusOr<int> column = Column(name);
  if (!column.ok()) return column.status();
  std::vector<std::pair<long, std::vector<std::string>>> keyed;
  for (std::vector<std::string>& row : rows_) {
    long key = 0;
    if (!absl::SimpleAtoi(row[*column], &key)) {
      return absl::InvalidArgumentError(absl::StrCat("column ", name, ": \"", row[*column], "\" is not an integer"));
    }
    keyed.emplace_back(key, std::move(row));
  }
  std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  rows_.clear();
  for (auto& [key, row] : keyed) rows_.push_back(std::move(row));
  return absl::OkStatus();
}

std::string RunTable::ToCsv() const {
  std::string out = absl::StrCat(absl::StrJoin(columns_, ","), "\n");
  for (const std::vector<std::string>& row : rows_) absl::StrAppend(&out, absl::StrJoin(row, ","), "\n");
  return out;
}

absl::Status RunTable::Write(const std::string& path) const {
  std::ofstream out(path);
  out << ToCsv();
  out.close();
  if (!out) return absl::InternalError(absl::StrCat(path, ": cannot write"));
  return absl::OkStatus();
}

absl::StatusOr<RunTable> RunTable::Read(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open"));
  std::string line;
  if (!std::getline(in, line) || line.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ":1: no header line"));
  }
  RunTable table(absl::StrSplit(line, ','));
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty()) continue;
    std::vector<std::string> row = absl::StrSplit(line, ',');
    if (row.size() != table.columns_.size()) {
      return absl::InvalidArgumentError(absl::StrCat(path, ":", line_number, ": ", row.size(),
                                                     " values, the header has ", table.columns_.size(), " columns"));
    }
    table.rows_.push_back(std::move(row));
  }
  return table;
}

std::string FormatNumber(double value) {
  if (std::isnan(value)) return "nan";
  char buffer[64];
  for (int digits = 6; digits <= 17; ++digits) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", digits, value);
    if (std::strtod(buffer, nullptr) == value) break;
  }
  return buffer;
}

}  // namespace subslam::study
