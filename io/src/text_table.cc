#include "subslam/io/text_table.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace subslam::io {

absl::StatusOr<std::string> ReadFileToString(const std::string& path) {
  // A directory, device or pipe named where a file is expected is refused before it is
  // opened: reading /dev/zero or a FIFO would never end.
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (!error && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": not a regular file"));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open file"));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return absl::DataLossError(absl::StrCat(path, ": read error"));
  return buffer.str();
}

absl::StatusOr<std::vector<TextRow>> ReadTextTable(const std::string& path,
                                                   const std::vector<std::string>& column_names, int max_columns,
                                                   bool allow_empty) {
  absl::StatusOr<std::string> text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseTextTable(*text, path, column_names, max_columns, allow_empty);
}

absl::StatusOr<std::vector<TextRow>> ParseTextTable(absl::string_view text, const std::string& path,
                                                    const std::vector<std::string>& column_names, int max_columns,
                                                    bool allow_empty) {
  std::vector<TextRow> rows;
  std::vector<absl::string_view> fields;
  const auto separator = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  // A field's name, for an error message only.
  const auto name = [&column_names](int i) {
    return i < static_cast<int>(column_names.size()) ? column_names[i] : absl::StrCat("column ", i + 1);
  };
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line.front() == '#') continue;
    // Fields separated by runs of blanks, tabs and carriage returns.
    fields.clear();
    for (size_t k = 0; k < line.size();) {
      while (k < line.size() && separator(line[k])) ++k;
      size_t end = k;
      while (end < line.size() && !separator(line[end])) ++end;
      if (end > k) fields.push_back(line.substr(k, end - k));
      k = end;
    }
    const int n = static_cast<int>(fields.size());
    if (n < static_cast<int>(column_names.size())) {
      return absl::InvalidArgumentError(absl::StrCat(path, ":", line_number, ": expected at least ",
                                                     column_names.size(), " columns, found ", n, " (missing field '",
                                                     column_names[n], "')"));
    }
    if (max_columns > 0 && n > max_columns) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": expected at most ", max_columns, " columns, found ", n));
    }
    TextRow row;
    row.line = line_number;
    row.values.resize(n);
    for (int i = 0; i < n; ++i) {
      double value = 0.0;
      if (!absl::SimpleAtod(fields[i], &value)) {
        return absl::InvalidArgumentError(absl::StrCat(path, ":", line_number, ": field '", name(i), "' (column ",
                                                       i + 1, ") is not a number: '", fields[i], "'"));
      }
      if (!std::isfinite(value)) {
        return absl::InvalidArgumentError(absl::StrCat(path, ":", line_number, ": field '", name(i), "' (column ",
                                                       i + 1, ") is not finite: '", fields[i], "'"));
      }
      row.values[i] = value;
    }
    rows.push_back(std::move(row));
  }
  if (rows.empty() && !allow_empty) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": file has no data lines"));
  }
  return rows;
}

}  // namespace subslam::io
