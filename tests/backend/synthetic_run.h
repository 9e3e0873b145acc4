// Synthetic local maps for the back-end tests: a square loop of anchors, landmarks along
// it at least 4 m apart, and per leg a local map with the true relative end pose and the
// landmarks within 15 m, corrupted by a draw from its own random covariance.
#ifndef SUBSLAM_TESTS_BACKEND_SYNTHETIC_RUN_H_
#define SUBSLAM_TESTS_BACKEND_SYNTHETIC_RUN_H_

#include <Eigen/Cholesky>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

// A synthetic run: anchors along a square loop, landmarks along it, and for each leg a
// local map with the true relative end pose and the landmarks within 15 m of the leg,
// corrupted by a draw from its own random covariance Q.
struct SyntheticRun {
  std::vector<Pose2> anchors;  // truth, anchors[0] = initial pose
  std::vector<Eigen::Vector2d> landmarks;
  std::vector<LocalSubmap> submaps;
};

inline SyntheticRun MakeRun(uint64_t seed, int legs = 12, double noise = 1.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  SyntheticRun run;
  run.anchors.push_back(Pose2(0, 0, 0.2));
  for (int k = 0; k < legs; ++k) {
    const double turn = (k % 3 == 2) ? kPi / 2 : 0.05 * uniform(rng);
    run.anchors.push_back(Compose(run.anchors.back(), Pose2(10.0, 0.5 * uniform(rng), turn)));
  }
  for (int k = 0; k <= legs; ++k) {
    for (int i = 0; i < 3; ++i) {  // at least 4 m apart
      const Eigen::Vector2d p =
          TransformFrom(run.anchors[k], Eigen::Vector2d(5 * i, 6 * uniform(rng) + (i % 2 ? 8 : -8)));
      bool clear = true;
      for (const Eigen::Vector2d& q : run.landmarks) clear = clear && (q - p).norm() >= 4.0;
      if (clear) run.landmarks.push_back(p);
    }
  }
  for (int k = 0; k < legs; ++k) {
    const Pose2& s = run.anchors[k];
    const Pose2& e = run.anchors[k + 1];
    LocalSubmap m;
    m.id = k;
    m.t_start = 10.0 * k;
    m.t_end = 10.0 * (k + 1);
    std::vector<Eigen::Vector2d> seen;
    std::vector<int> ids;
    for (size_t j = 0; j < run.landmarks.size(); ++j) {
      if ((run.landmarks[j] - s.translation()).norm() < 15.0 || (run.landmarks[j] - e.translation()).norm() < 15.0) {
        seen.push_back(run.landmarks[j]);
        ids.push_back(static_cast<int>(j));
      }
    }
    const int dim = 3 + 2 * static_cast<int>(seen.size());
    // A random correlation structure with set standard deviations: 0.1 m for the end
    // position, 0.005 rad for its heading, 0.15 m for the landmarks (× noise).
    Eigen::MatrixXd A(dim, dim);
    for (int r = 0; r < dim; ++r) {
      for (int c = 0; c < dim; ++c) A(r, c) = normal(rng) / std::sqrt(dim);
    }
    const Eigen::MatrixXd C = A * A.transpose() + Eigen::MatrixXd::Identity(dim, dim);
    Eigen::VectorXd sigma = Eigen::VectorXd::Constant(dim, 0.15 * noise);
    sigma.head<3>() << 0.1 * noise, 0.1 * noise, 0.005 * noise;
    const Eigen::VectorXd d = C.diagonal().cwiseSqrt().cwiseInverse().cwiseProduct(sigma);
    const Eigen::MatrixXd Q = d.asDiagonal() * C * d.asDiagonal();
    Eigen::VectorXd draw(dim);
    for (int r = 0; r < dim; ++r) draw[r] = normal(rng);
    const Eigen::VectorXd truth = PredictSubmap(s, e, seen);
    m.mean = truth + Eigen::LLT<Eigen::MatrixXd>(Q).matrixL() * draw;
    m.mean[2] = WrapAngle(m.mean[2]);
    m.covariance = Q;
    for (size_t i = 0; i < seen.size(); ++i) m.landmarks.push_back({static_cast<int>(i), NAN, 1.0, ids[i], 1, {}});
    run.submaps.push_back(m);
  }
  return run;
}

// Known association, relinearised to convergence at Finish(): the Gauss-Newton reference.
inline EifJoinerOptions ConvergingKnownAssociation() {
  EifJoinerOptions o;
  o.association.known_association = true;
  o.relinearize_at_end = true;
  o.relinearize_tolerance = 1e-12;
  o.relinearize_step_chi2 = 0.0;  // the step test would stop about 1e-5 m short
  o.predict_convergence = false;  // every iteration taken
  o.max_relinearizations = 50;
  return o;
}

// Every anchor (1 …) then every landmark of a joiner, stacked, headings wrapped.
inline Eigen::VectorXd StackedEstimate(const MapJoiner& j) {
  Eigen::VectorXd x(3 * (j.num_anchors() - 1) + 2 * j.num_landmarks());
  for (int k = 1; k < j.num_anchors(); ++k) x.segment<3>(3 * (k - 1)) = j.anchor(k).vector();
  for (int l = 0; l < j.num_landmarks(); ++l) x.segment<2>(3 * (j.num_anchors() - 1) + 2 * l) = j.landmark(l);
  return x;
}

// RMS of the anchors' position errors (anchor 0, fixed, left out).
inline double AnchorRms(const SubmapGraph& graph, const SyntheticRun& run) {
  double sum = 0.0;
  for (int k = 1; k < graph.num_anchors(); ++k) {
    sum += (graph.anchors()[k].translation() - run.anchors[k].translation()).squaredNorm();
  }
  return std::sqrt(sum / (graph.num_anchors() - 1));
}

// Landmarks by truth: how many distinct truths, and landmarks holding features of two.
struct TruthCount {
  int landmarks = 0, truths = 0, mixed = 0;
};
inline TruthCount CountByTruth(const SubmapGraph& g) {
  std::map<int, std::set<int>> truths_of;
  std::set<int> truths;
  for (const SubmapFactor& f : g.factors()) {
    for (int i = 0; i < f.submap.num_landmarks(); ++i) {
      truths_of[f.landmark_of_feature[i]].insert(*f.submap.landmarks[i].truth_id);
      truths.insert(*f.submap.landmarks[i].truth_id);
    }
  }
  TruthCount c{g.num_landmarks(), static_cast<int>(truths.size()), 0};
  for (const auto& [j, t] : truths_of) c.mixed += t.size() > 1 ? 1 : 0;
  return c;
}

}  // namespace subslam::backend

#endif  // SUBSLAM_TESTS_BACKEND_SYNTHETIC_RUN_H_
