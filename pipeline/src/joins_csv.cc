#include "joins_csv.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace subslam::pipeline {

std::string JoinsCsv(const std::vector<backend::JoinSummary>& joins) {
  std::string csv = "map_id,seconds";
  for (const backend::JoinerCounters::Field& f : backend::JoinerCounters::Fields()) absl::StrAppend(&csv, ",", f.name);
  csv += "\n";
  for (const backend::JoinSummary& j : joins) {
    absl::StrAppend(&csv, j.map_id, ",", absl::StrFormat("%.6f", j.seconds));
    for (const backend::JoinerCounters::Field& f : backend::JoinerCounters::Fields()) {
      absl::StrAppend(&csv, ",", j.counts.*f.member);
    }
    csv += "\n";
  }
  return csv;
}

}  // namespace subslam::pipeline
