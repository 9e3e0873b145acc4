// Writing a Dataset as a data-set directory (`dataset.json` + text files) that
// ReadDataset reads back to the same values (numbers written with 17 significant
// digits, so the round trip is exact).
#ifndef SUBSLAM_IO_DATASET_WRITER_H_
#define SUBSLAM_IO_DATASET_WRITER_H_

#include <string>

#include "absl/status/status.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

// Extra manifest content describing how a simulated data set was made; written to the
// manifest's "simulation" object (ignored by the reader).
struct SimulationInfo {
  std::string scenario;
  uint64_t seed = 0;
  double detection_probability = 1.0;
  double false_alarm_probability = 0.0;
};

// Creates `directory` if needed and writes dataset.json, controls.dat,
// observations.dat and, when present, truth_poses.dat, truth_landmarks.dat, gps.dat.
absl::Status WriteDataset(const Dataset& dataset, const std::string& directory,
                          const SimulationInfo* simulation = nullptr);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_DATASET_WRITER_H_
