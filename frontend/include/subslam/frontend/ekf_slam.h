// EKF-SLAM with unknown data association (known association: a study option, see
// EkfSlamOptions::known_association): the single-map baseline (Smith, Self &
// Cheeseman; as used in HybridSLAM §4 and FMJ §II), and the filter inside the EKF local
// mapper (ekf_local_mapper.h).
//
// State [pose (3), landmark 1 (2), …] with a dense covariance (conventions.h).
//  * Predict: the motion model on the vehicle block only — O(n).
//  * Odometry self-calibration (optional, EkfSlamOptions::odometry; odometry_calibration.h):
//    the vehicle block also holds c = (s0, s1, b), state [pose (3), c (3), landmark 1 (2),
//    …]. The parameters are constant (their prediction is the identity; their Jacobian
//    G·∂u'/∂c links them to the pose), so the filter learns them from what the landmarks
//    say about the motion. Reset() keeps their estimate and covariance and drops their
//    correlation with what it forgets.
//  * Update, per scan: predicted measurements of the landmarks in range; individual
//    compatibility gating by χ²₂(gate_probability); association by nearest neighbour
//    or JCBB (data_association.h); one batch EKF update of all pairings,
//    P ← P − (PHᵀ) S⁻¹ (PHᵀ)ᵀ as a symmetric rank-2k update — O(k n²).
//  * New landmarks: a detection incompatible with every landmark at the larger
//    χ²₂(new_landmark_probability) gate is initialised from the inverse sensor model
//    with the exact cross-covariances. Detections between the two gates are ambiguous
//    and dropped.
//  * Existence (existence_model.h, HybridSLAM §3.2, Eq. 11): each landmark carries
//    P(exists), raised by a detection and lowered when it is predicted well inside the
//    field of view and no detection even gated with it. Tentative landmarks below the
//    delete threshold are removed from the state, so false alarms do not become
//    landmarks; confirmed ones are reported by Map() and kept. Removal is batched every
//    `cull_every_scans` scans.
//
// Memory: the covariance lives in a capacity-doubling buffer, so adding a landmark is
// O(n) amortised; deleting one compacts the state in O(n²).
// Not thread-safe.
#ifndef SUBSLAM_FRONTEND_EKF_SLAM_H_
#define SUBSLAM_FRONTEND_EKF_SLAM_H_

#include <memory>
#include <vector>

#include "absl/status/status.h"
#include "subslam/association/data_association.h"
#include "subslam/frontend/innovation_monitor.h"
#include "subslam/frontend/landmark_options.h"
#include "subslam/frontend/moment_matching.h"
#include "subslam/frontend/odometry_calibration.h"
#include "subslam/frontend/online_estimator.h"
#include "subslam/models/motion_model.h"
#include "subslam/models/range_bearing_model.h"

namespace subslam::frontend {

struct EkfSlamOptions {
  association::AssociationMethod association = association::AssociationMethod::kNearestNeighbour;
  long jcbb_max_nodes = 20000;  // JCBB search budget per scan
  LandmarkOptions landmarks;    // gates, known association, existence
  // Divergence: the windowed normalised innovation test over the associated detections
  // (innovation_monitor.h), counted in Counters().
  InnovationTestOptions innovation_test;
  OdometryCalibrationOptions odometry;

  absl::Status Validate() const;
};

struct EkfSlamCounters {
  long scans = 0;
  long detections = 0;
  long associated = 0;
  long new_landmarks = 0;
  long ambiguous = 0;          // dropped between the two gates
  long known_ignored = 0;      // known association: false alarms and repeated ids dropped
  long deleted_landmarks = 0;  // tentative landmarks removed
  long jcbb_truncated = 0;
  // The prediction-error decomposition of the likelihood: over every scan's associated
  // detections, −log N(ν; 0, S) of the joint innovation, and its dimension (2 per
  // pairing). Its minimum over an unknown model parameter is the parameter's maximum
  // likelihood estimate (bench/sensor_yaw_calibration).
  double innovation_neg_log_likelihood = 0.0;
  long innovation_dof = 0;
  // Numerical failures: an innovation covariance that is not positive definite. The
  // pairing (or, for the joint update, the scan's update) is skipped and counted.
  long numerical_failures = 0;
};

class EkfSlam final : public OnlineEstimator {
 public:
  // The start pose is known exactly unless a prior covariance is given (SeifSlam needs
  // one; giving the EKF the same makes the two comparable).
  EkfSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
          const Pose2& initial_pose, const EkfSlamOptions& options,
          const Eigen::Matrix3d& initial_pose_covariance = Eigen::Matrix3d::Zero());

  std::string Name() const override { return "ekfslam"; }
  void Predict(const Eigen::Vector2d& u, double dt) override;
  absl::Status Update(const Scan& scan) override;
  Pose2 pose() const override;
  Eigen::Matrix3d pose_covariance() const override;
  std::vector<LandmarkEstimate> Map() const override;
  StageTimes stage_times() const override { return times_; }
  std::map<std::string, double> Counters() const override;

  // Starts over at `start` with zero uncertainty and no landmarks (a new local map).
  // Landmark ids keep increasing across resets; the odometry calibration carries over.
  void Reset(const Pose2& start);
  // The pose and the landmarks with existence ≥ min_existence as one Gaussian, in the
  // filter's frame: mean [pose, l_1, …], features = landmark ids (increasing), the
  // existence of each; signature NaN (EKF-SLAM does not track signatures).
  MomentMatchedGaussian Export(double min_existence) const;
  // The landmark id each detection of the last scan was associated with or created
  // (−1: out of range, ambiguous), aligned with the scan's detections.
  const std::vector<int>& last_scan_features() const { return scan_features_; }
  // Confirmed landmarks, and those within sensor range of the current pose.
  int NumConfirmed() const;
  int NumConfirmedWithinRange() const;

  // The odometry calibration now (value (1, 1, 0) and zero covariance when off).
  OdometryCalibrationEstimate odometry_calibration() const;

  // All landmarks in the state, tentative ones included.
  int num_landmarks() const { return static_cast<int>(landmarks_.size()); }
  int state_dimension() const { return dim_; }
  const EkfSlamCounters& counters() const { return counters_; }
  // The full state mean and covariance (views valid until the next call).
  Eigen::VectorXd mean() const { return x_.head(dim_); }
  Eigen::MatrixXd covariance() const { return P_.topLeftCorner(dim_, dim_).selfadjointView<Eigen::Lower>(); }

 private:
  struct LandmarkInfo {
    int id = 0;         // stable id reported in Map()
    int truth_id = -1;  // known association only
    double existence = 0.5;
    bool confirmed = false;
  };
  struct Prediction {  // of one landmark's measurement
    int landmark = -1;
    Eigen::Vector2d z = Eigen::Vector2d::Zero();
    Matrix23d H_pose;
    Eigen::Matrix2d H_landmark;
    Eigen::Matrix2d S;
  };

  int Offset(int landmark) const { return vehicle_dim_ + 2 * landmark; }
  void Reserve(int dim);
  // Predict() with the odometry calibration in the state.
  void PredictCalibrated(const Eigen::Vector2d& u, double dt);
  void AddLandmark(const Eigen::Vector2d& z, int truth_id);
  // Known association: each usable detection's landmark by its true id (−1: none yet, a
  // new one; kDropped: a false alarm or an id already detected in this scan), and the id.
  static constexpr int kDropped = -2;
  std::vector<int> KnownLandmarks(const Scan& scan, const std::vector<int>& detection_index,
                                  std::vector<int>* truth_of_detection) const;
  // Individual compatibility of every detection with every predicted landmark: the
  // candidates inside the gate (sorted by d²), each detection's smallest d², and which
  // landmarks some detection falls near enough not to start a new one.
  void GateDetections(const std::vector<Eigen::Vector2d>& z, const std::vector<Prediction>& predictions,
                      association::AssociationProblem* problem, std::vector<double>* min_d2, std::vector<bool>* gated);
  // Known association: the pairing the true ids give (an unseen id starts a landmark later).
  association::AssociationResult AssociateByTruth(const std::vector<Eigen::Vector2d>& z,
                                                  const std::vector<int>& known_landmark,
                                                  const std::vector<Prediction>& predictions,
                                                  const std::vector<int>& prediction_of_landmark,
                                                  association::AssociationProblem* problem, std::vector<bool>* gated);
  // The batch EKF update with every (detection, landmark) pairing of a scan.
  void UpdateWithPairings(const std::vector<std::pair<int, const association::AssociationCandidate*>>& pairs,
                          const std::vector<Prediction>& predictions, const std::vector<int>& prediction_of_landmark,
                          const Eigen::Matrix2d& R);
  // Existence of the paired and of the expected but missed landmarks, new landmarks for
  // detections beyond every gate, and the periodic cull of tentative landmarks.
  void ManageLandmarks(const std::vector<Eigen::Vector2d>& z, const std::vector<int>& detection_index,
                       const std::vector<std::pair<int, const association::AssociationCandidate*>>& pairs,
                       const std::vector<Prediction>& predictions, const std::vector<bool>& gated,
                       const std::vector<int>& landmark_of_detection, const std::vector<int>& known_landmark,
                       const std::vector<int>& truth_of_detection, const std::vector<double>& min_d2);
  void RemoveLandmarks(const std::vector<int>& sorted_indices);
  Eigen::Matrix2d CrossCovariance(const Prediction& a, const Prediction& b) const;
  // Covariance access under the storage invariant (see P_).
  Eigen::Matrix2d LandmarkCovarianceBlock(int oa, int ob) const;
  void LandmarkColumns(int offset, Eigen::Ref<Eigen::MatrixXd> out) const;
  void SyncPoseRows();
  void UpdateExistence(LandmarkInfo* info, bool detected) const;

  std::unique_ptr<models::MotionModel> motion_;
  models::RangeBearingModel sensor_;
  EkfSlamOptions options_;
  double gate_d2_ = 0.0, new_landmark_d2_ = 0.0;
  int vehicle_dim_ = 3;  // the pose, and the odometry calibration's three when on
  int dim_ = 3;
  Eigen::VectorXd x_;
  // capacity × capacity; the top-left dim_ × dim_ block is live. Storage invariant:
  // the lower triangle and the vehicle rows (0 to vehicle_dim_ − 1) are current; the landmark-landmark
  // part above the diagonal is stale (never read).
  Eigen::MatrixXd P_;
  std::vector<LandmarkInfo> landmarks_;
  int next_id_ = 0;
  EkfSlamCounters counters_;
  InnovationMonitor innovation_monitor_;
  StageTimes times_;
  std::vector<int> scan_features_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_EKF_SLAM_H_
