// Every back-end on the same recorded local maps: reads a submaps.jsonl (docs/formats.md,
// as `subslam run --frontend rbpf|ekf` writes it) and joins it with the EIF, Ceres, dense
// EKF joining and the binary tree over EKF and EIF nodes, then prints what each made of it.
//
//   compare_backends SUBMAPS_JSONL
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "subslam/io/submaps_jsonl.h"
#include "subslam/pipeline/submap_slam.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s SUBMAPS_JSONL\n", argv[0]);
    return 2;
  }
  absl::StatusOr<std::vector<subslam::LocalSubmap>> maps = subslam::io::ReadSubmapsJsonl(argv[1]);
  if (!maps.ok()) {
    std::fprintf(stderr, "%s\n", std::string(maps.status().message()).c_str());
    return 1;
  }
  using subslam::pipeline::Backend;
  std::printf("%zu local maps\n%-9s %9s %10s %26s %9s\n", maps->size(), "back-end", "landmarks", "merged",
              "last anchor (x, y, θ)", "time [s]");
  for (const Backend kind : {Backend::kEif, Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif}) {
    subslam::pipeline::BackendOptions options;
    options.kind = kind;
    // The first local map starts at the origin of the file's frame.
    std::unique_ptr<subslam::backend::MapJoiner> joiner = subslam::pipeline::MakeJoiner(options, subslam::Pose2());
    const auto start = std::chrono::steady_clock::now();
    for (const subslam::LocalSubmap& map : *maps) {
      if (absl::Status joined = joiner->Join(map); !joined.ok()) {
        std::fprintf(stderr, "%s: %s\n", subslam::pipeline::ToString(kind), std::string(joined.message()).c_str());
        return 1;
      }
    }
    if (absl::Status finished = joiner->Finish(); !finished.ok()) {
      std::fprintf(stderr, "%s: %s\n", subslam::pipeline::ToString(kind), std::string(finished.message()).c_str());
      return 1;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const subslam::Pose2 last = joiner->LastAnchor();
    std::printf("%-9s %9d %10ld   (%7.2f, %7.2f, %6.3f) %9.3f\n", subslam::pipeline::ToString(kind),
                joiner->num_landmarks(), joiner->counters().landmarks_merged, last.x, last.y, last.theta, seconds);
  }
  return 0;
}
