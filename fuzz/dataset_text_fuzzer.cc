// libFuzzer target for the data set's text files (io/dataset_reader.h): the first input
// byte picks the file (its value mod 5: controls, observations, GPS, true poses, true
// landmarks) and the motion model (bit 3: Ackermann, which bounds the steering angle), the
// rest is that file; the manifest and the other files are fixed and valid. Whatever the
// text, ReadDataset must return a data set or an error naming file, line and field, and an
// accepted data set must hold the invariants of dataset_fuzz_check.h. Built and run by
// scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "dataset_fuzz_check.h"
#include "subslam/io/dataset_reader.h"

namespace {

std::string Manifest(bool ackermann) {
  const std::string motion =
      ackermann ? R"("model": "ackermann", "wheelbase": 2.83, "sigma_steer": 0.01,)"
                : R"("model": "unicycle", "sigma_omega": 0.01,)";
  return absl::StrCat(R"({"format": "subslam-dataset/1", "name": "fuzz", "motion": {)", motion,
                      R"( "controls_file": "controls.dat", "sigma_v": 0.1},
 "sensor": {"type": "range_bearing", "observations_file": "observations.dat",
            "sigma_range": 0.1, "sigma_bearing": 0.01, "max_range": 30,
            "signature_column": 5, "truth_id_column": 4},
 "ground_truth": {"gps_file": "gps.dat", "poses_file": "truth_poses.dat",
                  "landmarks_file": "truth_landmarks.dat"}})");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const char* kNames[] = {"fuzz/controls.dat", "fuzz/observations.dat", "fuzz/gps.dat",
                                 "fuzz/truth_poses.dat", "fuzz/truth_landmarks.dat"};
  std::map<std::string, std::string> files = {
      {"fuzz/controls.dat", "0 1.0 0.1\n0.1 1.0 0.1\n0.2 1.2 -0.2\n"},
      {"fuzz/observations.dat", "0.1 5.0 0.3 1 7\n0.1 6.0 -0.3 2 7\n0.2 4.0 3.0 -1 1\n"},
      {"fuzz/gps.dat", "0 0 0\n0.2 0.2 0.01\n"},
      {"fuzz/truth_poses.dat", "0 0 0 0\n0.1 0.1 0 0.01\n"},
      {"fuzz/truth_landmarks.dat", "1 4 2\n2 5 -2\n"}};
  files["fuzz/dataset.json"] = Manifest((data[0] & 8) != 0);
  files[kNames[data[0] % 5]] = std::string(reinterpret_cast<const char*>(data) + 1, size - 1);
  const subslam::io::FileReader read = [&](const std::string& path) -> absl::StatusOr<std::string> {
    const auto it = files.find(path);
    if (it == files.end()) return absl::NotFoundError(absl::StrCat(path, ": cannot open file"));
    return it->second;
  };
  absl::StatusOr<subslam::io::Dataset> d = subslam::io::ReadDataset("fuzz", read);
  if (!d.ok()) {
    subslam::fuzz::Require(!d.status().message().empty());
    return 0;
  }
  subslam::fuzz::CheckAcceptedDataset(*d);
  return 0;
}
