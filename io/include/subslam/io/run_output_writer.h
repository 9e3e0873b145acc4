// Writers for the run outputs of docs/formats.md ("Run outputs"):
//   trajectory_online.csv / trajectory_final.csv: t,x,y,theta,cov_xx,cov_xy,cov_xt,cov_yy,cov_yt,cov_tt
//   landmarks.csv: id,x,y,cov_xx,cov_xy,cov_yy
// and a helper to write a text file (report.json is built by the caller).
#ifndef SUBSLAM_IO_RUN_OUTPUT_WRITER_H_
#define SUBSLAM_IO_RUN_OUTPUT_WRITER_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/graph/estimates.h"

namespace subslam::io {

absl::Status WriteTrajectoryCsv(const std::string& path, const Trajectory& trajectory);
absl::Status WriteLandmarksCsv(const std::string& path,
                               const std::vector<LandmarkEstimate>& landmarks);
absl::Status WriteTextFile(const std::string& path, const std::string& content);

// Reads a trajectory CSV written by WriteTrajectoryCsv (for tools and tests).
absl::StatusOr<Trajectory> ReadTrajectoryCsv(const std::string& path);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_RUN_OUTPUT_WRITER_H_
