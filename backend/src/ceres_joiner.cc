#include "subslam/backend/ceres_joiner.h"

#include <algorithm>

#include "absl/time/clock.h"

namespace subslam::backend {
namespace {

EifJoinerOptions WithoutGaussNewtonAtEnd(EifJoinerOptions options) {
  options.relinearize_at_end = false;
  return options;
}

}  // namespace

absl::Status CeresJoinerOptions::Validate() const {
  if (absl::Status st = eif.Validate(); !st.ok()) return st;
  if (absl::Status st = solve.Validate(); !st.ok()) return st;
  if (solve_every < 0) return absl::InvalidArgumentError("ceres solve_every must be >= 0");
  return absl::OkStatus();
}

CeresJoiner::CeresJoiner(const Pose2& initial_pose, const CeresJoinerOptions& options)
    : options_(options), eif_(initial_pose, WithoutGaussNewtonAtEnd(options.eif)) {}

absl::Status CeresJoiner::JoinLocalMap(const LocalSubmap& submap) {
  if (absl::Status st = eif_.Join(submap); !st.ok()) return st;
  ++joins_;
  if (options_.solve_every > 0 && joins_ % options_.solve_every == 0) return SolveAndAdopt();
  return absl::OkStatus();
}

std::unique_ptr<MapJoiner> CeresJoiner::NewEmpty(const Pose2& initial_pose) const {
  return std::make_unique<CeresJoiner>(initial_pose, options_);
}

std::unique_ptr<MapJoiner> CeresJoiner::Clone() const { return std::make_unique<CeresJoiner>(*this); }

absl::Status CeresJoiner::JoinMap(const MapJoiner& right_base) {
  const auto* right = dynamic_cast<const CeresJoiner*>(&right_base);
  if (right == nullptr) return absl::InvalidArgumentError("Ceres JoinMap: the right map is not a Ceres map");
  if (absl::Status st = eif_.JoinMap(right->eif_); !st.ok()) return st;
  joins_ += right->joins_;
  solves_ += right->solves_;
  iterations_ += right->iterations_;
  seconds_ += right->seconds_;
  max_seconds_ = std::max(max_seconds_, right->max_seconds_);
  return absl::OkStatus();
}

absl::Status CeresJoiner::Finish() {
  if (absl::Status st = eif_.Finish(); !st.ok()) return st;
  return SolveAndAdopt();
}

absl::Status CeresJoiner::SolveAndAdopt() {
  if (eif_.graph().factors().empty()) return absl::OkStatus();
  const absl::Time start = absl::Now();
  SubmapGraph g = eif_.graph();  // warm start: the current estimate
  absl::StatusOr<CeresSolveReport> r = SolveWithCeres(&g, options_.solve);
  if (!r.ok()) return r.status();
  last_solve_ = *r;
  ++solves_;
  iterations_ += r->iterations;
  if (absl::Status st = eif_.AdoptEstimate(g); !st.ok()) return st;
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
  seconds_ += seconds;
  max_seconds_ = std::max(max_seconds_, seconds);
  return absl::OkStatus();
}

std::map<std::string, double> CeresJoiner::stage_times() const {
  std::map<std::string, double> times = eif_.stage_times();
  if (solves_ > 0) times["ceres_solve_and_adopt"] = seconds_;
  return times;
}

JoinerExtras CeresJoiner::Extras() const {
  JoinerExtras extras;
  if (!last_solve_) return extras;
  extras.figures = {{"ceres_solves", solves_},
                    {"ceres_iterations_total", static_cast<double>(iterations_)},
                    {"ceres_max_solve_and_adopt_seconds", max_seconds_},
                    {"ceres_iterations", last_solve_->iterations},
                    {"ceres_initial_cost", last_solve_->initial_cost},
                    {"ceres_final_cost", last_solve_->final_cost}};
  extras.notes = {{"ceres_termination", last_solve_->termination}, {"ceres_brief", last_solve_->brief}};
  return extras;
}

}  // namespace subslam::backend
