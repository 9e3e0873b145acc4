// End-to-end benchmark of the Victoria Park runs: reads the data set, runs each
// front-end (dead reckoning, EKF-SLAM, the RBPF and EKF local mappers) and prints wall
// time (read; estimator, i.e. the whole step loop; front-end, i.e. the sum of the
// filter's stage times; total), time per scan, local maps, peak resident memory and the
// aligned RMS of trajectory_final against GPS. Each front-end runs in its own child
// process so that its peak memory is its own.
//
//   build/bench/victoria_park_bench [--dataset DIR] [--frontends a,b] [--repeats N] [--out results.json]
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "keep_freed_memory_flag.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/pipeline/run_pipeline.h"

ABSL_FLAG(std::string, dataset, SUBSLAM_DEFAULT_VICTORIA_PARK, "Victoria Park data-set directory");
ABSL_FLAG(int, repeats, 3, "runs per front-end (the median is reported)");
ABSL_FLAG(std::string, out, "", "write the results as JSON here");
ABSL_FLAG(std::string, frontends, "odometry,ekfslam,rbpf,ekf", "front-ends to run, comma-separated");

namespace {

struct Measurement {
  double read_s = 0, estimator_s = 0, frontend_s = 0, total_s = 0, rms_m = 0;
  long peak_kb = 0;
  size_t landmarks = 0, local_maps = 0;
  int scans = 0;
  double mean_map_landmarks = 0;
  int max_map_landmarks = 0;
  double tenths[10] = {};  // seconds spent in each tenth of the steps
};

// Runs one front-end in this (child) process and writes its measurement to `fd`.
int RunChild(subslam::pipeline::Frontend frontend, int fd) {
  const absl::Time start = absl::Now();
  auto d = subslam::io::ReadDataset(absl::GetFlag(FLAGS_dataset));
  if (!d.ok()) {
    std::fprintf(stderr, "%s\n", std::string(d.status().message()).c_str());
    return 1;
  }
  const double read_s = absl::ToDoubleSeconds(absl::Now() - start);
  subslam::pipeline::RunOptions options;
  options.frontend = frontend;
  auto r = subslam::pipeline::RunPipeline(*std::move(d), options);
  if (!r.ok() || !r->gps_final) return 1;
  Measurement m;
  m.read_s = read_s;
  m.estimator_s = r->wall_seconds;
  m.total_s = absl::ToDoubleSeconds(absl::Now() - start);
  m.rms_m = r->gps_final->rms_m;
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  m.peak_kb = usage.ru_maxrss;
  m.landmarks = r->landmarks.size();
  m.local_maps = r->local_maps.size();
  for (const subslam::LocalSubmap& s : r->local_maps) {
    m.mean_map_landmarks += s.num_landmarks();
    m.max_map_landmarks = std::max(m.max_map_landmarks, s.num_landmarks());
  }
  if (m.local_maps > 0) m.mean_map_landmarks /= static_cast<double>(m.local_maps);
  for (size_t k = 0; k < r->wall_seconds_by_tenth.size() && k < 10; ++k) {
    m.tenths[k] = r->wall_seconds_by_tenth[k] - (k == 0 ? 0.0 : r->wall_seconds_by_tenth[k - 1]);
  }
  m.scans = r->scans;
  for (const auto& [stage, seconds] : r->report["time_seconds"]["stages"].items()) {
    m.frontend_s += seconds.get<double>();
  }
  return write(fd, &m, sizeof(m)) == sizeof(m) ? 0 : 1;
}

bool Measure(subslam::pipeline::Frontend frontend, Measurement* m) {
  int fds[2];
  if (pipe(fds) != 0) return false;
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    _exit(RunChild(frontend, fds[1]));
  }
  close(fds[1]);
  const bool ok = read(fds[0], m, sizeof(*m)) == sizeof(*m);
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return ok && WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  const int repeats = std::max(1, absl::GetFlag(FLAGS_repeats));
  nlohmann::json results = nlohmann::json::array();
  std::printf("%-9s %7s %11s %10s %8s %11s %8s %10s %9s %10s\n", "frontend", "read_s", "estimator_s", "frontend_s",
              "total_s", "us_per_scan", "peak_MB", "local_maps", "landmarks", "gps_rms_m");
  const std::vector<std::string> names = absl::StrSplit(absl::GetFlag(FLAGS_frontends), ',');
  for (const std::string& name : names) {
    const absl::StatusOr<subslam::pipeline::Frontend> parsed = subslam::pipeline::FrontendFromString(name);
    if (!parsed.ok()) {
      std::fprintf(stderr, "%s\n", std::string(parsed.status().message()).c_str());
      return 1;
    }
    const subslam::pipeline::Frontend frontend = *parsed;
    std::vector<Measurement> runs;
    for (int i = 0; i < repeats; ++i) {
      Measurement m;
      if (!Measure(frontend, &m)) {
        std::fprintf(stderr, "run failed\n");
        return 1;
      }
      runs.push_back(m);
    }
    std::sort(runs.begin(), runs.end(),
              [](const Measurement& a, const Measurement& b) { return a.total_s < b.total_s; });
    const Measurement& med = runs[runs.size() / 2];
    long peak = 0;
    for (const Measurement& m : runs) peak = std::max(peak, m.peak_kb);
    std::printf("%-9s %7.3f %11.3f %10.3f %8.3f %11.1f %8.1f %10zu %9zu %10.2f\n",
                subslam::pipeline::ToString(frontend), med.read_s, med.estimator_s, med.frontend_s, med.total_s,
                1e6 * med.frontend_s / std::max(1, med.scans), peak / 1024.0, med.local_maps, med.landmarks, med.rms_m);
    results.push_back({{"frontend", subslam::pipeline::ToString(frontend)},
                       {"repeats", repeats},
                       {"median_read_s", med.read_s},
                       {"median_estimator_s", med.estimator_s},
                       {"median_frontend_s", med.frontend_s},
                       {"frontend_us_per_scan", 1e6 * med.frontend_s / std::max(1, med.scans)},
                       {"local_maps", med.local_maps},
                       {"mean_landmarks_per_local_map", med.mean_map_landmarks},
                       {"max_landmarks_per_local_map", med.max_map_landmarks},
                       {"seconds_per_tenth_of_steps", std::vector<double>(med.tenths, med.tenths + 10)},
                       {"median_total_s", med.total_s},
                       {"max_peak_rss_mb", peak / 1024.0},
                       {"landmarks", med.landmarks},
                       {"aligned_gps_rms_m", med.rms_m}});
  }
  std::printf("\nseconds spent in each tenth of the steps (median run):\n");
  for (const auto& entry : results) {
    std::printf("%-9s", entry["frontend"].get<std::string>().c_str());
    for (double t : entry["seconds_per_tenth_of_steps"]) std::printf(" %6.3f", t);
    std::printf("   local maps: mean %.1f, max %d landmarks\n", entry["mean_landmarks_per_local_map"].get<double>(),
                entry["max_landmarks_per_local_map"].get<int>());
  }
  if (!absl::GetFlag(FLAGS_out).empty()) {
    std::ofstream(absl::GetFlag(FLAGS_out)) << results.dump(2) << "\n";
  }
  return 0;
}
