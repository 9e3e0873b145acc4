#include "subslam/frontend/moment_matching.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "subslam/core/check.h"

namespace subslam::frontend {
namespace {

// One particle's resolved hypothesis about one common feature.
struct Resolved {
  Eigen::Vector2d mean;
  Eigen::Matrix2d covariance;
  double existence;
  double signature;
};

Resolved Fuse(const Resolved& a, const FeatureHypothesis& b) {
  // Product of the two Gaussians (information form).
  const Eigen::Matrix2d ia = a.covariance.inverse(), ib = b.covariance.inverse();
  Resolved out = a;
  out.covariance = (ia + ib).inverse();
  out.mean = out.covariance * (ia * a.mean + ib * b.mean);
  out.existence = std::max(a.existence, b.existence);
  return out;
}

// The particle's features sorted by common id, duplicates resolved.
std::vector<std::pair<int, Resolved>> ResolveDuplicates(const ParticleHypothesis& p, DuplicateFeaturePolicy policy) {
  // Sort indices, not the Eigen-holding records (std::stable_sort's scratch buffer is
  // not over-aligned for fixed-size Eigen members).
  std::vector<int> order(p.features.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::sort(order.begin(), order.end(), [&p](int a, int b) {
    return p.features[a].feature < p.features[b].feature || (p.features[a].feature == p.features[b].feature && a < b);
  });
  std::vector<std::pair<int, Resolved>> out;
  out.reserve(order.size());
  for (int k : order) {
    const FeatureHypothesis& f = p.features[k];
    const int id = f.feature;
    const Resolved r{f.mean, f.covariance, f.existence, f.signature};
    if (out.empty() || out.back().first != id) {
      out.push_back({id, r});
    } else if (policy == DuplicateFeaturePolicy::kFuse) {
      out.back().second = Fuse(out.back().second, f);
    } else if (r.existence > out.back().second.existence) {
      out.back().second = r;
    }
  }
  return out;
}

}  // namespace

bool RepairCovariance(Eigen::MatrixXd* covariance, double relative_floor) {
  // Positive definite and conditioned well enough to be whitened by a joiner: kept as is.
  // The Cholesky factor's reciprocal condition estimate (1-norm, O(n²)) settles the usual
  // case: 1/κ₁ ≤ 1/κ₂ = λ_min/λ_max, and the factor 10³ leaves room for the estimate,
  // which may overstate 1/κ₁ (in practice by a factor of about 3 at most).
  const Eigen::LLT<Eigen::MatrixXd> llt(*covariance);
  if (llt.info() == Eigen::Success && llt.rcond() >= 1e3 * relative_floor) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(*covariance);
  const double floor = std::max(relative_floor * eig.eigenvalues().cwiseAbs().maxCoeff(), 1e-15);
  if (llt.info() == Eigen::Success && eig.eigenvalues().minCoeff() >= floor) return false;
  *covariance = eig.eigenvectors() * eig.eigenvalues().cwiseMax(floor).asDiagonal() * eig.eigenvectors().transpose();
  *covariance = 0.5 * (*covariance + covariance->transpose()).eval();
  return true;
}

double SharedAncestrySpreadScale(double shared_ancestry) {
  // S / (1 − R) estimates Σ; the mean's own Monte Carlo error adds R Σ.
  return (1.0 + shared_ancestry) / (1.0 - shared_ancestry);
}

namespace {

// The particles' features, duplicates resolved, and each particle's normalised weight.
struct ParticleFeatures {
  std::vector<std::vector<std::pair<int, Resolved>>> resolved;  // per particle, by id
  std::vector<double> w;                                        // weights, then those taking part
  std::vector<std::vector<const Resolved*>> held;               // per particle, per exported feature
};

// The exported features: those whose existence, summed over the particles' weights,
// reaches min_existence.
void ChooseFeatures(std::span<const ParticleHypothesis> particles, double total, const MomentMatchingOptions& options,
                    ParticleFeatures* f, MomentMatchedGaussian* out) {
  std::vector<std::vector<std::pair<int, Resolved>>>& resolved = f->resolved;
  resolved.resize(particles.size());
  std::vector<std::pair<int, double>> all;  // (id, weighted existence) from every particle
  for (size_t p = 0; p < particles.size(); ++p) {
    resolved[p] = ResolveDuplicates(particles[p], options.duplicates);
    for (const auto& [id, r] : resolved[p]) all.push_back({id, particles[p].weight / total * r.existence});
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::pair<int, double>> existence;
  for (const auto& [id, e] : all) {
    if (existence.empty() || existence.back().first != id) {
      existence.push_back({id, e});
    } else {
      existence.back().second += e;
    }
  }
  for (const auto& [id, e] : existence) {
    if (e >= options.min_existence && e > 0.0) {  // e > 0: a holder has weight
      out->features.push_back(id);
      out->existence.push_back(std::min(e, 1.0));
    }
  }
}

// Which particles take part (with kDiscardParticle, only those holding every exported
// feature, unless none does) and which features each holds.
void WeighParticles(std::span<const ParticleHypothesis> particles, double total, const MomentMatchingOptions& options,
                    ParticleFeatures* f, MomentMatchedGaussian* out) {
  const int n = static_cast<int>(out->features.size());
  std::vector<double>& w = f->w;
  const std::vector<std::vector<std::pair<int, Resolved>>>& resolved = f->resolved;
  w.resize(particles.size());
  f->held.assign(particles.size(), std::vector<const Resolved*>(n, nullptr));
  std::vector<std::vector<const Resolved*>>& held = f->held;
  for (size_t p = 0; p < particles.size(); ++p) {
    w[p] = particles[p].weight / total;
    size_t next = 0;  // both lists are sorted by id: merge
    for (int k = 0; k < n; ++k) {
      while (next < resolved[p].size() && resolved[p][next].first < out->features[k]) ++next;
      if (next < resolved[p].size() && resolved[p][next].first == out->features[k]) {
        held[p][k] = &resolved[p][next].second;
      }
    }
  }
  if (options.missing == MissingFeaturePolicy::kDiscardParticle) {
    double kept = 0.0;
    for (size_t p = 0; p < particles.size(); ++p) {
      const bool all = std::all_of(held[p].begin(), held[p].end(), [](const Resolved* r) { return r != nullptr; });
      if (all) kept += w[p];
    }
    if (kept > 0.0) {
      for (size_t p = 0; p < particles.size(); ++p) {
        const bool all = std::all_of(held[p].begin(), held[p].end(), [](const Resolved* r) { return r != nullptr; });
        w[p] = all ? w[p] / kept : 0.0;
      }
    } else {
      out->fell_back_to_ignore = true;
    }
  }
  for (double wp : w) out->particles_used += wp > 0.0 ? 1 : 0;
}

// The means: the pose over every particle taking part (heading as wrapped deviations from
// the heaviest particle's), each feature and its signature over the particles holding it.
void Means(std::span<const ParticleHypothesis> particles, size_t heaviest, const ParticleFeatures& f,
           MomentMatchedGaussian* out_ptr) {
  MomentMatchedGaussian& out = *out_ptr;
  const int n = static_cast<int>(out.features.size());
  const int dim = 3 + 2 * n;
  const std::vector<double>& w = f.w;
  const std::vector<std::vector<const Resolved*>>& held = f.held;
  const double reference = particles[heaviest].pose.theta;
  out.mean = Eigen::VectorXd::Zero(dim);
  Eigen::VectorXd weight_of(n + 1);
  weight_of.setZero();
  out.signature.assign(n, 0.0);
  std::vector<double> signature_weight(n, 0.0);
  for (size_t p = 0; p < particles.size(); ++p) {
    if (w[p] == 0.0) continue;
    const Pose2& pose = particles[p].pose;
    out.mean.head<3>() += w[p] * Eigen::Vector3d(pose.x, pose.y, WrapAngle(pose.theta - reference));
    weight_of[0] += w[p];
    for (int k = 0; k < n; ++k) {
      const Resolved* r = held[p][k];
      if (r == nullptr) continue;
      out.mean.segment<2>(3 + 2 * k) += w[p] * r->mean;
      weight_of[k + 1] += w[p];
      if (std::isfinite(r->signature)) {
        out.signature[k] += w[p] * r->signature;
        signature_weight[k] += w[p];
      }
    }
  }
  out.mean.head<3>() /= weight_of[0];
  for (int k = 0; k < n; ++k) {
    out.mean.segment<2>(3 + 2 * k) /= weight_of[k + 1];  // > 0 since existence > 0
    out.signature[k] =
        signature_weight[k] > 0.0 ? out.signature[k] / signature_weight[k] : std::numeric_limits<double>::quiet_NaN();
  }
  out.mean[2] = WrapAngle(out.mean[2] + reference);
}

// The covariance when every particle taking part holds every exported feature (the usual
// case): P = Σ_p w_p P_p + s · D W Dᵀ with D the deviations, one product.
void CompleteCovariance(std::span<const ParticleHypothesis> particles, const ParticleFeatures& f, double spread_scale,
                        MomentMatchedGaussian* out_ptr) {
  MomentMatchedGaussian& out = *out_ptr;
  const int n = static_cast<int>(out.features.size());
  const int dim = 3 + 2 * n;
  const std::vector<double>& w = f.w;
  const std::vector<std::vector<const Resolved*>>& held = f.held;
  int used = 0;
  for (double wp : w) used += wp > 0.0 ? 1 : 0;
  Eigen::MatrixXd D(dim, used);
  out.covariance = Eigen::MatrixXd::Zero(dim, dim);
  int c = 0;
  for (size_t p = 0; p < particles.size(); ++p) {
    if (w[p] == 0.0) continue;
    const Pose2& pose = particles[p].pose;
    const double sw = std::sqrt(w[p] * spread_scale);
    D(0, c) = sw * (pose.x - out.mean[0]);
    D(1, c) = sw * (pose.y - out.mean[1]);
    D(2, c) = sw * WrapAngle(pose.theta - out.mean[2]);
    out.covariance.topLeftCorner<3, 3>() += w[p] * particles[p].pose_covariance;
    for (int k = 0; k < n; ++k) {
      const int o = 3 + 2 * k;
      D.block<2, 1>(o, c) = sw * (held[p][k]->mean - out.mean.segment<2>(o));
      out.covariance.block<2, 2>(o, o) += w[p] * held[p][k]->covariance;
    }
    ++c;
  }
  out.covariance.selfadjointView<Eigen::Lower>().rankUpdate(D);
  out.covariance.triangularView<Eigen::StrictlyUpper>() = out.covariance.transpose();
}

// The covariance block by block, each over the particles holding both of its variables.
void BlockwiseCovariance(std::span<const ParticleHypothesis> particles, const ParticleFeatures& f, double spread_scale,
                         MomentMatchedGaussian* out_ptr) {
  MomentMatchedGaussian& out = *out_ptr;
  const int n = static_cast<int>(out.features.size());
  const int dim = 3 + 2 * n;
  const std::vector<double>& w = f.w;
  const std::vector<std::vector<const Resolved*>>& held = f.held;
  out.covariance = Eigen::MatrixXd::Zero(dim, dim);
  Eigen::MatrixXd pair_weight = Eigen::MatrixXd::Zero(n + 1, n + 1);
  Eigen::VectorXd d(dim);
  std::vector<bool> has(n + 1);
  for (size_t p = 0; p < particles.size(); ++p) {
    if (w[p] == 0.0) continue;
    const Pose2& pose = particles[p].pose;
    d.head<2>() = Eigen::Vector2d(pose.x, pose.y) - out.mean.head<2>();
    d[2] = WrapAngle(pose.theta - out.mean[2]);
    has[0] = true;
    for (int k = 0; k < n; ++k) {
      has[k + 1] = held[p][k] != nullptr;
      d.segment<2>(3 + 2 * k) =
          has[k + 1] ? Eigen::Vector2d(held[p][k]->mean - out.mean.segment<2>(3 + 2 * k)) : Eigen::Vector2d::Zero();
    }
    auto offset = [](int b) { return b == 0 ? 0 : 3 + 2 * (b - 1); };
    auto size = [](int b) { return b == 0 ? 3 : 2; };
    for (int a = 0; a <= n; ++a) {
      if (!has[a]) continue;
      for (int b = 0; b <= a; ++b) {
        if (!has[b]) continue;
        pair_weight(a, b) += w[p];
        out.covariance.block(offset(a), offset(b), size(a), size(b)) +=
            w[p] * spread_scale * d.segment(offset(a), size(a)) * d.segment(offset(b), size(b)).transpose();
      }
      out.covariance.block(offset(a), offset(a), size(a), size(a)) +=
          w[p] * (a == 0 ? Eigen::MatrixXd(particles[p].pose_covariance) : Eigen::MatrixXd(held[p][a - 1]->covariance));
    }
  }
  for (int a = 0; a <= n; ++a) {
    const int oa = a == 0 ? 0 : 3 + 2 * (a - 1), sa = a == 0 ? 3 : 2;
    for (int b = 0; b <= a; ++b) {
      const int ob = b == 0 ? 0 : 3 + 2 * (b - 1), sb = b == 0 ? 3 : 2;
      if (pair_weight(a, b) > 0.0) out.covariance.block(oa, ob, sa, sb) /= pair_weight(a, b);
      out.covariance.block(ob, oa, sb, sa) = out.covariance.block(oa, ob, sa, sb).transpose();
    }
  }
}

}  // namespace

MomentMatchedGaussian MomentMatch(std::span<const ParticleHypothesis> particles, const MomentMatchingOptions& options,
                                  double shared_ancestry) {
  SUBSLAM_CHECK(shared_ancestry >= 0.0 && shared_ancestry < 1.0) << "shared ancestry " << shared_ancestry;
  const double spread_scale = SharedAncestrySpreadScale(shared_ancestry);
  double total = 0.0;
  size_t heaviest = 0;
  for (size_t p = 0; p < particles.size(); ++p) {
    const double w = particles[p].weight;
    SUBSLAM_CHECK(std::isfinite(w) && w >= 0.0) << "particle weight " << w;
    total += w;
    if (w > particles[heaviest].weight) heaviest = p;
  }
  SUBSLAM_CHECK(total > 0.0) << "moment matching needs a particle with positive weight";
  MomentMatchedGaussian out;
  ParticleFeatures f;
  ChooseFeatures(particles, total, options, &f, &out);
  WeighParticles(particles, total, options, &f, &out);
  Means(particles, heaviest, f, &out);
  bool complete = true;
  for (size_t p = 0; p < particles.size() && complete; ++p) {
    if (f.w[p] == 0.0) continue;
    for (const Resolved* r : f.held[p]) complete = complete && r != nullptr;
  }
  if (complete) {
    CompleteCovariance(particles, f, spread_scale, &out);
  } else {
    BlockwiseCovariance(particles, f, spread_scale, &out);
  }
  // Positive definiteness: repair (counted) if the per-block weighting broke it.
  if (RepairCovariance(&out.covariance, options.repair_relative_floor)) ++out.covariance_repairs;
  return out;
}

}  // namespace subslam::frontend
