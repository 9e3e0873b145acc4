// libFuzzer target for the data set's text files (io/dataset_reader.h): the first input
// byte picks the file (its value mod 5: controls, observations, GPS, true poses, true
// landmarks) and the motion model (bit 3: Ackermann, which bounds the steering angle), the
// rest is that file; the manifest and the other files are fixed and valid. Whatever the
// text, ReadDataset must return a data set or an error naming file, line and field, and an
// accepted data set must hold the invariants of dataset_fuzz.h. Built and run by
// scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "dataset_fuzz.h"
#include "subslam/io/dataset_reader.h"

namespace {

std::string Manifest(bool ackermann) {
  const std::string motion = ackermann ? R"("model": "ackermann", "wheelbase": 2.83, "sigma_steer": 0.01,)"
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
  static const char* kNames[] = {"fuzz/controls.dat", "fuzz/observations.dat", "fuzz/gps.dat", "fuzz/truth_poses.dat",
                                 "fuzz/truth_landmarks.dat"};
  std::map<std::string, std::string> files = subslam::fuzz::ValidTextFiles();
  files["fuzz/dataset.json"] = Manifest((data[0] & 8) != 0);
  files[kNames[data[0] % 5]] = std::string(reinterpret_cast<const char*>(data) + 1, size - 1);
  subslam::fuzz::ReadAndCheck(files);
  return 0;
}
