// The calibration's estimate and its rounds (robot_calibration.h; internal to the module).
#ifndef SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_STATE_H_
#define SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_STATE_H_

#include <ceres/problem.h>

#include <Eigen/Core>
#include <array>
#include <map>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/calibration/internal/calibration_costs.h"
#include "subslam/calibration/odometry_interval.h"
#include "subslam/calibration/robot_calibration.h"
#include "subslam/io/dataset.h"
#include "subslam/io/steps.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/scan.h"

namespace subslam::calibration::internal {

// θ's order: the four control-noise components, σ_r², σ_b², then the factor λ on the
// odometry covariance of intervals that span a control gap.
constexpr int kComponents = 7;
constexpr int kRangeComponent = 4, kBearingComponent = 5, kGapComponent = 6;

class CalibrationState {
 public:
  CalibrationState(const io::Dataset& dataset, const CalibrationOptions& options);

  // Pose 0 is the data set's initial pose (held); each scan has a pose (a scan at the
  // first step's time shares pose 0).
  const std::vector<int>& pose_of_scan() const { return pose_of_scan_; }
  int num_poses() const { return num_poses_; }
  void SetPoses(std::vector<Eigen::Vector3d> poses, const std::vector<Eigen::Matrix3d>& scan_covariances);
  // Unknown association: the map to pair with. Known association: ignored, the landmarks
  // start where their detections put them from the start poses.
  void SetLandmarks(const std::vector<Eigen::Vector2d>& map, const std::vector<Eigen::Matrix2d>& covariances);

  absl::StatusOr<RobotCalibration> Run();

 private:
  struct Interval {
    int a = 0, b = 0;  // pose indices
    OdometryInterval odometry;
    bool gap = false;  // spans a control gap
  };
  struct Pairing {
    int scan = 0, detection = 0, landmark = 0;
  };
  // What a round's variance step reads.
  struct RoundSums {
    std::array<double, kComponents> weighted{};  // vᵀ W T_k W v
    std::array<double, kComponents> expected{};  // tr(W T_k W Q_vv)
  };

  struct OdometryTerm {
    const OdometryCost* cost;
    Eigen::Matrix3d S;                 // the whitening, L⁻¹ for Σ = L Lᵀ
    std::array<Eigen::Matrix3d, 4> T;  // the covariance components
  };

  void BuildIntervals(const std::vector<io::Step>& steps);
  void BuildProblem(ceres::Problem* problem, std::vector<OdometryTerm>* odometry,
                    std::vector<const DetectionCost*>* detections);
  absl::Status Fit(ceres::Problem* problem) const;
  // Moves the paired detections whose residual fails the test to the outliers; their count.
  int DropOutliers();
  bool IsOutlier(const Pairing& p, double bound) const;
  void LandmarksFromTruth();
  void Pair();
  void PairByGate();
  absl::StatusOr<RoundSums> SolveRound();
  void FlagOutliers();
  RobotCalibration Result(int rounds, bool converged, int outliers_left_out) const;
  void DetectionCurve(const std::set<int>& landmarks, RobotCalibration* r) const;
  std::vector<std::pair<double, double>> ControlGaps() const;
  Eigen::Matrix3d OdometryCovariance(const std::array<Eigen::Matrix3d, 4>& T, bool gap) const;
  Eigen::Vector2d SensorSigma() const;

  const io::Dataset& dataset_;
  CalibrationOptions options_;
  models::RangeBearingModel sensor_;
  std::unique_ptr<models::MotionModel> model_;
  Eigen::Vector3d c_;  // (s₀, s₁, o₁)
  std::array<double, kComponents> theta_{};
  std::array<double, kComponents> redundancy_{};  // θ_k · tr(W T_k W Q_vv), the last round's
  std::vector<Interval> intervals_;
  std::vector<int> pose_of_scan_;
  int num_poses_ = 1;
  std::vector<Eigen::Vector3d> poses_;
  std::vector<Eigen::Vector2d> landmarks_;
  std::vector<Eigen::Matrix3d> pose_covariance_;      // the last round's marginals
  std::vector<Eigen::Matrix2d> landmark_covariance_;  // (zero: not known)
  Eigen::Matrix3d correction_covariance_ = Eigen::Matrix3d::Constant(NAN);
  std::vector<Pairing> pairs_;
  std::set<std::pair<int, int>> outliers_;  // (scan, detection) left out
  std::map<int, int> landmark_of_truth_;    // known association
  int observations_ = 0, unknowns_ = 0;     // the last round's
};

}  // namespace subslam::calibration::internal

#endif  // SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_STATE_H_
