// Writers for the run outputs of docs/formats.md ("Run outputs"):
//   trajectory_online.csv / trajectory_final.csv: t,x,y,theta,cov_xx,cov_xy,cov_xt,cov_yy,cov_yt,cov_tt
//   landmarks.csv: id,x,y,cov_xx,cov_xy,cov_yy
//   *.tum: a trajectory in the TUM RGB-D format ("t x y z qx qy qz qw", z = 0, the
//          heading as a rotation about z), which evo and similar tools read directly;
//   truth_trajectory.csv: t,x,y,theta; truth_landmarks.csv: id,x,y (the ground truth);
//   gps_aligned.csv: t,x,y,rejected — GPS fixes moved into the estimate's frame;
// and a helper to write a text file (report.json is built by the caller).
#ifndef SUBSLAM_IO_RUN_OUTPUT_WRITER_H_
#define SUBSLAM_IO_RUN_OUTPUT_WRITER_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/estimates.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

absl::Status WriteTrajectoryCsv(const std::string& path, const Trajectory& trajectory);
absl::Status WriteLandmarksCsv(const std::string& path, const std::vector<LandmarkEstimate>& landmarks);
absl::Status WriteTextFile(const std::string& path, const std::string& content);

absl::Status WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);
absl::Status WriteTumTrajectory(const std::string& path, const std::vector<TimedPose>& poses);
absl::Status WriteTruthTrajectoryCsv(const std::string& path, const std::vector<TimedPose>& poses);
absl::Status WriteTruthLandmarksCsv(const std::string& path, const std::vector<TruthLandmark>& landmarks);
// `rejected[i]`: fix i is a gross fault the GPS metric drops (empty: none).
absl::Status WriteGpsCsv(const std::string& path, const std::vector<TimedPoint>& fixes,
                         const std::vector<bool>& rejected);

// Reads a trajectory CSV written by WriteTrajectoryCsv (for tools and tests).
absl::StatusOr<Trajectory> ReadTrajectoryCsv(const std::string& path);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_RUN_OUTPUT_WRITER_H_
