// Dense Gauss-Newton over a submap graph, the reference the EIF's relinearisation is
// checked against (tests only).
#ifndef SUBSLAM_TESTS_BACKEND_DENSE_GAUSS_NEWTON_H_
#define SUBSLAM_TESTS_BACKEND_DENSE_GAUSS_NEWTON_H_

#include <Eigen/Core>
#include <Eigen/LU>

#include "subslam/backend/submap_factor.h"
#include "subslam/core/submap_graph.h"
#include "synthetic_run.h"

namespace subslam::backend {

// Dense Gauss-Newton over the same graph, from the joiner's association and initial
// guess: the reference for "iterated to convergence = batch Gauss-Newton".
inline Eigen::VectorXd DenseGaussNewton(const SubmapGraph& graph, int iterations) {
  const int A = graph.num_anchors() - 1, L = graph.num_landmarks();
  const int n = 3 * A + 2 * L;
  Eigen::VectorXd x(n);
  for (int k = 1; k <= A; ++k) x.segment<3>(3 * (k - 1)) = graph.anchors()[k].vector();
  for (int j = 0; j < L; ++j) x.segment<2>(3 * A + 2 * j) = graph.landmarks()[j];
  for (int it = 0; it < iterations; ++it) {
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    const auto pose = [&](int k) { return k == 0 ? graph.anchors()[0] : Pose2::FromVector(x.segment<3>(3 * (k - 1))); };
    for (const SubmapFactor& f : graph.factors()) {
      std::vector<Eigen::Vector2d> lms;
      for (int j : f.landmark_of_feature) lms.push_back(x.segment<2>(3 * A + 2 * j));
      const SubmapFactorLinearization lin =
          LinearizeSubmapFactor(f.submap, pose(f.start_anchor), pose(f.end_anchor), lms);
      Eigen::MatrixXd J = Eigen::MatrixXd::Zero(lin.residual.size(), n);
      if (f.start_anchor > 0) J.middleCols<3>(3 * (f.start_anchor - 1)) = lin.J_start;
      J.middleCols<3>(3 * (f.end_anchor - 1)) = lin.J_end;
      for (size_t i = 0; i < f.landmark_of_feature.size(); ++i) {
        J.middleCols<2>(3 * A + 2 * f.landmark_of_feature[i]) += lin.J_landmarks.middleCols<2>(2 * i);
      }
      const Eigen::MatrixXd W = f.submap.covariance.inverse();
      H += J.transpose() * W * J;
      g += J.transpose() * W * lin.residual;
    }
    x -= H.ldlt().solve(g);
  }
  return x;
}

}  // namespace subslam::backend

#endif  // SUBSLAM_TESTS_BACKEND_DENSE_GAUSS_NEWTON_H_
