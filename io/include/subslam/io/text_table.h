// Line-oriented reading of whitespace-separated numeric text files, with errors that
// name the file, line and column. Empty lines and lines starting with '#' are skipped.
#ifndef SUBSLAM_IO_TEXT_TABLE_H_
#define SUBSLAM_IO_TEXT_TABLE_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace subslam::io {

struct TextRow {
  int line = 0;                // 1-based line number in the file
  std::vector<double> values;  // all finite
};

// Reads every data line of `path`. Each row must have at least `column_names.size()`
// columns (the names are used in error messages) and at most `max_columns` (0: no
// limit); every value must parse as a finite number. An empty file (no data line) is
// an error unless `allow_empty`.
absl::StatusOr<std::vector<TextRow>> ReadTextTable(const std::string& path,
                                                   const std::vector<std::string>& column_names, int max_columns = 0,
                                                   bool allow_empty = false);

// The same for a text already in memory; `path` names it in error messages.
absl::StatusOr<std::vector<TextRow>> ParseTextTable(absl::string_view text, const std::string& path,
                                                    const std::vector<std::string>& column_names, int max_columns = 0,
                                                    bool allow_empty = false);

// Reads a whole regular file into a string (a directory, device or pipe is an error).
absl::StatusOr<std::string> ReadFileToString(const std::string& path);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_TEXT_TABLE_H_
