// libFuzzer target for the data-set manifest (dataset.json; io/dataset_reader.h): the
// input is the manifest, and the text files it may name (controls.dat, observations.dat,
// gps.dat, truth_poses.dat, truth_landmarks.dat) hold a few valid lines each. Whatever
// the manifest, ReadDataset must return a data set or an error naming the file (never
// crash, hang or read out of bounds), and an accepted data set must hold the invariants of
// dataset_fuzz_check.h. Built and run by scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "dataset_fuzz_check.h"
#include "subslam/io/dataset_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::map<std::string, std::string> kFiles = {
      {"fuzz/controls.dat", "0 1.0 0.1\n0.1 1.0 0.1\n0.2 1.2 -0.2\n"},
      {"fuzz/observations.dat", "0.1 5.0 0.3 1 7\n0.1 6.0 -0.3 2 7\n0.2 4.0 3.0 -1 1\n"},
      {"fuzz/gps.dat", "0 0 0\n0.2 0.2 0.01\n"},
      {"fuzz/truth_poses.dat", "0 0 0 0\n0.1 0.1 0 0.01\n"},
      {"fuzz/truth_landmarks.dat", "1 4 2\n2 5 -2\n"}};
  const std::string manifest(reinterpret_cast<const char*>(data), size);
  const subslam::io::FileReader read = [&](const std::string& path) -> absl::StatusOr<std::string> {
    if (path == "fuzz/dataset.json") return manifest;
    const auto it = kFiles.find(path);
    if (it == kFiles.end()) return absl::NotFoundError(absl::StrCat(path, ": cannot open file"));
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
