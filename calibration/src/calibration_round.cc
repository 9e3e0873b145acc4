// One round of the calibration: the Gauss-Newton fit at the current noise, then the sums
// of the variance-component step (robot_calibration.h, step 2).
#include <ceres/covariance.h>
#include <ceres/normal_prior.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <memory>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "subslam/calibration/internal/calibration_costs.h"
#include "subslam/calibration/internal/calibration_state.h"

namespace subslam::calibration::internal {
namespace {

using BlockPair = std::pair<const double*, const double*>;

// The covariance of the blocks `blocks` (sizes `sizes`) as one matrix; a null block (the
// held initial pose) has zero rows and columns.
Eigen::MatrixXd JointCovariance(const ceres::Covariance& covariance, const std::vector<const double*>& blocks,
                                const std::vector<int>& sizes) {
  int n = 0;
  std::vector<int> offset;
  for (int s : sizes) {
    offset.push_back(n);
    n += s;
  }
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
  for (size_t a = 0; a < blocks.size(); ++a) {
    for (size_t b = a; b < blocks.size(); ++b) {
      if (blocks[a] == nullptr || blocks[b] == nullptr) continue;
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> block(sizes[a], sizes[b]);
      covariance.GetCovarianceBlock(blocks[a], blocks[b], block.data());
      C.block(offset[a], offset[b], sizes[a], sizes[b]) = block;
      C.block(offset[b], offset[a], sizes[b], sizes[a]) = block.transpose();
    }
  }
  return C;
}

void RequestPairs(const std::vector<const double*>& blocks, std::set<BlockPair>* pairs) {
  for (size_t a = 0; a < blocks.size(); ++a) {
    for (size_t b = a; b < blocks.size(); ++b) {
      if (blocks[a] == nullptr || blocks[b] == nullptr) continue;
      pairs->insert(blocks[a] < blocks[b] ? BlockPair(blocks[a], blocks[b]) : BlockPair(blocks[b], blocks[a]));
    }
  }
}

// tr(T̃ (I − G)) and ẽᵀ T̃ ẽ for whitened residual e, T̃ = S T Sᵀ.
void AddComponent(const Eigen::MatrixXd& T_whitened, const Eigen::VectorXd& e, const Eigen::MatrixXd& G,
                  double* weighted, double* expected) {
  *weighted += e.dot(T_whitened * e);
  *expected += (T_whitened * (Eigen::MatrixXd::Identity(G.rows(), G.cols()) - G)).trace();
}

}  // namespace

void CalibrationState::BuildProblem(ceres::Problem* problem, std::vector<OdometryTerm>* odometry,
                                    std::vector<const DetectionCost*>* detections) {
  problem->AddParameterBlock(poses_[0].data(), 3);
  problem->SetParameterBlockConstant(poses_[0].data());
  odometry->clear();
  odometry->reserve(intervals_.size());
  for (const Interval& iv : intervals_) {
    std::array<Eigen::Matrix3d, 4> T = iv.odometry.NoiseComponents(c_);
    const Eigen::Matrix3d L = OdometryCovariance(T, iv.gap).llt().matrixL();
    const Eigen::Matrix3d S = L.inverse();
    auto* cost = new OdometryCost(&iv.odometry, S);
    problem->AddResidualBlock(cost, nullptr, poses_[iv.a].data(), poses_[iv.b].data(), c_.data());
    odometry->push_back({cost, S, T});
  }
  if (options_.scale_prior_sigma > 0.0) {  // each scale ~ N(the data set's, scale_prior_sigma²)
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(2, 3);
    A(0, 0) = A(1, 1) = 1.0 / options_.scale_prior_sigma;
    const Eigen::Vector3d prior(dataset_.motion.control_scale[0], dataset_.motion.control_scale[1], 0.0);
    problem->AddResidualBlock(new ceres::NormalPrior(A, prior), nullptr, c_.data());
  }
  const Eigen::Vector2d sigma = SensorSigma();
  detections->clear();
  for (const Pairing& p : pairs_) {
    auto* cost = new DetectionCost(&sensor_, dataset_.scans[p.scan].detections[p.detection].z(), sigma);
    problem->AddResidualBlock(cost, nullptr, poses_[pose_of_scan_[p.scan]].data(), landmarks_[p.landmark].data());
    detections->push_back(cost);
  }
}

absl::Status CalibrationState::Fit(ceres::Problem* problem) const {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options_.max_solver_iterations;
  solver_options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, problem, &summary);
  if (!summary.IsSolutionUsable()) {
    return absl::InternalError(absl::StrCat("calibration: the fit failed: ", summary.message));
  }
  return absl::OkStatus();
}

absl::StatusOr<CalibrationState::RoundSums> CalibrationState::SolveRound() {
  // The fit, repeated without the paired detections its residuals reject (a few times at
  // most), so that a wrong pairing neither bends the poses nor reaches the variances.
  constexpr int kFitPasses = 4;
  std::unique_ptr<ceres::Problem> problem;
  std::vector<OdometryTerm> odometry;
  std::vector<const DetectionCost*> detection_costs;
  for (int pass = 0; pass < kFitPasses; ++pass) {
    problem = std::make_unique<ceres::Problem>();
    BuildProblem(problem.get(), &odometry, &detection_costs);
    if (absl::Status s = Fit(problem.get()); !s.ok()) return s;
    if (pass + 1 == kFitPasses || DropOutliers() == 0) break;
  }

  // The blocks each residual touches (null: the held initial pose).
  const auto pose_block = [&](int pose) -> const double* { return pose == 0 ? nullptr : poses_[pose].data(); };
  std::set<BlockPair> requested;
  for (const Interval& iv : intervals_) RequestPairs({pose_block(iv.a), pose_block(iv.b), c_.data()}, &requested);
  for (const Pairing& p : pairs_) {
    RequestPairs({pose_block(pose_of_scan_[p.scan]), landmarks_[p.landmark].data()}, &requested);
  }
  ceres::Covariance::Options covariance_options;
  ceres::Covariance covariance(covariance_options);
  if (!covariance.Compute(std::vector<BlockPair>(requested.begin(), requested.end()), problem.get())) {
    return absl::FailedPreconditionError(
        "calibration: the fit's information matrix is singular (a landmark or the correction is not observed)");
  }

  RoundSums sums;
  for (size_t i = 0; i < intervals_.size(); ++i) {
    const Interval& iv = intervals_[i];
    const OdometryTerm& term = odometry[i];
    const double* params[] = {poses_[iv.a].data(), poses_[iv.b].data(), c_.data()};
    Eigen::Vector3d e;
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> J[3];
    double* jacobians[] = {J[0].data(), J[1].data(), J[2].data()};
    term.cost->Evaluate(params, e.data(), jacobians);
    Eigen::Matrix<double, 3, 9> J_all;
    J_all << (iv.a == 0 ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(J[0])), J[1], J[2];
    const Eigen::MatrixXd C = JointCovariance(covariance, {pose_block(iv.a), pose_block(iv.b), c_.data()}, {3, 3, 3});
    const Eigen::MatrixXd G = J_all * C * J_all.transpose();
    if (iv.gap) {  // λ's only: Σ = λ Σ_k θ_k T_k
      AddComponent(term.S * OdometryCovariance(term.T, false) * term.S.transpose(), e, G, &sums.weighted[kGapComponent],
                   &sums.expected[kGapComponent]);
    } else {
      for (int k = 0; k < 4; ++k) {
        AddComponent(term.S * term.T[k] * term.S.transpose(), e, G, &sums.weighted[k], &sums.expected[k]);
      }
    }
    pose_covariance_[iv.b] = C.block<3, 3>(3, 3);
    if (i == 0) correction_covariance_ = C.block<3, 3>(6, 6);
  }
  for (size_t i = 0; i < pairs_.size(); ++i) {
    const Pairing& p = pairs_[i];
    const int pose = pose_of_scan_[p.scan];
    const double* params[] = {poses_[pose].data(), landmarks_[p.landmark].data()};
    Eigen::Vector2d e;
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J_x;
    Eigen::Matrix<double, 2, 2, Eigen::RowMajor> J_l;
    double* jacobians[] = {J_x.data(), J_l.data()};
    detection_costs[i]->Evaluate(params, e.data(), jacobians);
    Eigen::Matrix<double, 2, 5> J_all;
    J_all << (pose == 0 ? Eigen::Matrix<double, 2, 3>::Zero() : Eigen::Matrix<double, 2, 3>(J_x)), J_l;
    const Eigen::MatrixXd C = JointCovariance(covariance, {pose_block(pose), landmarks_[p.landmark].data()}, {3, 2});
    const Eigen::MatrixXd G = J_all * C * J_all.transpose();
    AddComponent(Eigen::Vector2d(1.0 / theta_[kRangeComponent], 0.0).asDiagonal().toDenseMatrix(), e, G,
                 &sums.weighted[kRangeComponent], &sums.expected[kRangeComponent]);
    AddComponent(Eigen::Vector2d(0.0, 1.0 / theta_[kBearingComponent]).asDiagonal().toDenseMatrix(), e, G,
                 &sums.weighted[kBearingComponent], &sums.expected[kBearingComponent]);
    landmark_covariance_[p.landmark] = C.block<2, 2>(3, 3);
  }
  for (int k = 0; k < kComponents; ++k) redundancy_[k] = theta_[k] * sums.expected[k];
  observations_ = 3 * static_cast<int>(intervals_.size()) + 2 * static_cast<int>(pairs_.size());
  unknowns_ = problem->NumParameters() - 3;
  return sums;
}

}  // namespace subslam::calibration::internal
