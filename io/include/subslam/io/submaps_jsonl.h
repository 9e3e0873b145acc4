// The local-maps exchange file `submaps.jsonl` (docs/formats.md, "Local maps exchange
// (submaps.jsonl)"): one JSON object per line, one line per local map, in order:
//   {"id": 3, "t_start": 30.0, "t_end": 40.0,
//    "state": [x, y, theta, l1x, l1y, …],          // end pose and landmarks, start frame
//    "cov": [(3+2n)² numbers, row-major],
//    "landmarks": [{"local_id": 0, "signature": 0.31 | null, "existence": 0.99,
//                   "truth_id": 17 | null}, …],
//    "covariance_repairs": 0}                       // optional (subslam extension)
// Numbers are written with enough digits to read back bit-identical.
// The reader checks every field and each local map's invariants
// (LocalSubmap::Validate) and names file, line and field in its errors; ids must
// increase from line to line. Two rules for local maps written by other tools: times
// may be absent or null (the map then spans zero time at the previous map's end), and a
// covariance that is symmetric and positive semidefinite but singular or numerically so
// is regularised (an indefinite one is an error) (LocalSubmap::RegularizeDegenerateCovariance, counted in
// covariance_repairs, which `subslam join` reports).
#ifndef SUBSLAM_IO_SUBMAPS_JSONL_H_
#define SUBSLAM_IO_SUBMAPS_JSONL_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/local_submap.h"

namespace subslam::io {

absl::Status WriteSubmapsJsonl(const std::string& path, const std::vector<LocalSubmap>& submaps);
absl::StatusOr<std::vector<LocalSubmap>> ReadSubmapsJsonl(const std::string& path);
// The same from the file's text in memory; `source` names it in errors.
absl::StatusOr<std::vector<LocalSubmap>> ParseSubmapsJsonl(const std::string& text, const std::string& source);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_SUBMAPS_JSONL_H_
