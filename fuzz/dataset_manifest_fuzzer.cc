// libFuzzer target for the data-set manifest (dataset.json; io/dataset_reader.h): the
// input is the manifest, and the text files it may name (controls.dat, observations.dat,
// gps.dat, truth_poses.dat, truth_landmarks.dat) hold a few valid lines each. Whatever
// the manifest, ReadDataset must return a data set or an error naming the file (never
// crash, hang or read out of bounds), and an accepted data set must hold the invariants of
// dataset_fuzz.h. Built and run by scripts/fuzz.sh.
#include <cstddef>
#include <cstdint>
#include <string>

#include "dataset_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::map<std::string, std::string> kFiles = subslam::fuzz::ValidTextFiles();
  std::map<std::string, std::string> files = kFiles;
  files["fuzz/dataset.json"] = std::string(reinterpret_cast<const char*>(data), size);
  subslam::fuzz::ReadAndCheck(files);
  return 0;
}
