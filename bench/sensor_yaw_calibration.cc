// Maximum-likelihood calibration of the sensor's yaw on the vehicle (a bearing offset
// beyond the data set's own), from the data alone: EKF-SLAM runs once per candidate yaw
// and sums the negative log-likelihood of its innovations (the prediction-error
// decomposition, frontend::EkfSlamCounters); the estimate is the minimum, refined by a
// parabola through the best grid point and its neighbours. GPS plays no part in the
// choice; its aligned RMS is printed beside each row for information only.
//
//   build/bench/sensor_yaw_calibration [--dataset DIR] [--from -0.04 --to 0.02 --step 0.005]
//                                      [--out results.json]
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/pipeline/run_pipeline.h"

ABSL_FLAG(std::string, dataset, SUBSLAM_DEFAULT_VICTORIA_PARK, "data-set directory");
ABSL_FLAG(double, from, -0.04, "first candidate yaw [rad]");
ABSL_FLAG(double, to, 0.02, "last candidate yaw [rad]");
ABSL_FLAG(double, step, 0.005, "grid step [rad]");
ABSL_FLAG(std::string, out, "", "write the table as JSON here");

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  const double from = absl::GetFlag(FLAGS_from), to = absl::GetFlag(FLAGS_to), step = absl::GetFlag(FLAGS_step);
  if (!(std::isfinite(from) && std::isfinite(to) && step > 0 && to >= from && (to - from) / step <= 1000)) {
    std::fprintf(stderr, "need finite --from <= --to and 0 < --step, at most 1000 points\n");
    return 2;
  }
  auto dataset = subslam::io::ReadDataset(absl::GetFlag(FLAGS_dataset));
  if (!dataset.ok()) {
    std::fprintf(stderr, "%s\n", std::string(dataset.status().message()).c_str());
    return 1;
  }
  struct Row {
    double yaw, nll_per_dof, rms_m;
    long dof;
  };
  std::vector<Row> rows;
  std::printf("%10s %14s %10s %14s\n", "yaw_rad", "nll_per_dof", "dof", "gps_rms_m");
  const int points = static_cast<int>(std::floor((to - from) / step + 1e-9)) + 1;
  for (int k = 0; k < points; ++k) {
    const double yaw = from + k * step;
    subslam::pipeline::RunOptions options;
    options.frontend = subslam::pipeline::Frontend::kEkfSlam;
    options.noise.sensor_yaw = yaw;
    absl::StatusOr<subslam::pipeline::RunResult> r = subslam::pipeline::RunPipeline(*dataset, options);
    if (!r.ok()) {
      std::fprintf(stderr, "yaw %g: %s\n", yaw, std::string(r.status().message()).c_str());
      return 1;
    }
    const nlohmann::json& c = r->report["estimator_counters"];
    const double nll = c["innovation_neg_log_likelihood"].get<double>();
    const long dof = static_cast<long>(c["innovation_dof"].get<double>());
    // Different yaws associate slightly different detections: compare per dimension.
    const Row row{yaw, nll / static_cast<double>(dof), r->gps_final ? r->gps_final->rms_m : NAN, dof};
    rows.push_back(row);
    std::printf("%10.4f %14.5f %10ld %14.2f\n", row.yaw, row.nll_per_dof, row.dof, row.rms_m);
  }
  size_t best = 0;
  for (size_t k = 1; k < rows.size(); ++k) {
    if (rows[k].nll_per_dof < rows[best].nll_per_dof) best = k;
  }
  double estimate = rows[best].yaw;
  if (best > 0 && best + 1 < rows.size()) {
    // Vertex of the parabola through the three points around the minimum.
    const double a = rows[best - 1].nll_per_dof, b = rows[best].nll_per_dof, c = rows[best + 1].nll_per_dof;
    const double curvature = a - 2 * b + c;
    if (curvature > 0) estimate += 0.5 * step * (a - c) / curvature;
  } else {
    std::printf("the minimum is at the edge of the grid: widen --from/--to\n");
  }
  std::printf("maximum-likelihood sensor yaw: %.4f rad (%.2f deg)\n", estimate, estimate * 180.0 / M_PI);
  if (const std::string out = absl::GetFlag(FLAGS_out); !out.empty()) {
    nlohmann::json j;
    j["dataset"] = absl::GetFlag(FLAGS_dataset);
    j["estimate_rad"] = estimate;
    for (const Row& row : rows) {
      j["rows"].push_back(
          {{"yaw_rad", row.yaw}, {"nll_per_dof", row.nll_per_dof}, {"dof", row.dof}, {"gps_rms_m", row.rms_m}});
    }
    std::ofstream(out) << j.dump(2) << "\n";
  }
  return 0;
}
