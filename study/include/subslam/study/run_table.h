// A study's per-run table (runs.csv, docs/formats.md "Study outputs"): one header line of
// column names, then one row per run, comma-separated, no quoting (no value holds a comma
// or a line break; Add() refuses one that does). Numbers are written by FormatNumber, so a
// table read back gives the values it was written with to the last printed digit, and a
// summary computed from the read-back table is the same whichever process wrote the rows.
#ifndef SUBSLAM_STUDY_RUN_TABLE_H_
#define SUBSLAM_STUDY_RUN_TABLE_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace subslam::study {

class RunTable {
 public:
  explicit RunTable(std::vector<std::string> columns);

  const std::vector<std::string>& columns() const { return columns_; }
  const std::vector<std::vector<std::string>>& rows() const { return rows_; }
  int num_rows() const { return static_cast<int>(rows_.size()); }

  // Index of a column; an error naming the table's columns if there is none.
  absl::StatusOr<int> Column(const std::string& name) const;

  // Appends a row; an error if its length is not the number of columns or a value holds
  // a comma or a line break.
  absl::Status Add(std::vector<std::string> row);

  // Value of `row` in column `name`: a string, or a number (an error naming the row and
  // column if it is not one).
  absl::StatusOr<std::string> Text(int row, const std::string& name) const;
  absl::StatusOr<double> Number(int row, const std::string& name) const;

  // Rows ordered by the integer in column `name` (stable).
  absl::Status SortBy(const std::string& name);

  std::string ToCsv() const;
  absl::Status Write(const std::string& path) const;
  // Reads a table written by Write(); errors name the file, line and column.
  static absl::StatusOr<RunTable> Read(const std::string& path);

 private:
  std::vector<std::string> columns_;
  std::vector<std::vector<std::string>> rows_;
};

// A number as runs.csv holds it: the shortest of %.*g (up to 17 digits) that reads back
// to the same double; "nan" for NaN.
std::string FormatNumber(double value);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_RUN_TABLE_H_
