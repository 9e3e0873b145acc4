// Reading a data-set directory (docs/formats.md, "Data-set directory").
//
// Everything is checked at this boundary; an error names the file, the line (for
// text files) and the field: a missing or mistyped manifest field, a short or
// non-numeric line, NaN or infinite values, times going backwards, a negative or
// zero σ, a non-positive range. Unknown manifest keys are rejected too, so a typo
// cannot silently fall back to a default. Nothing is half-loaded: on error no
// Dataset is returned.
#ifndef SUBSLAM_IO_DATASET_READER_H_
#define SUBSLAM_IO_DATASET_READER_H_

#include <functional>
#include <string>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

// Reads `directory`/dataset.json and the text files it names (`directory` may also be
// the path of the dataset.json itself).
absl::StatusOr<Dataset> ReadDataset(const std::string& directory);

// Returns the whole content of the file at a path, or an error naming it.
using FileReader = std::function<absl::StatusOr<std::string>(const std::string& path)>;

// The same with the files' contents supplied by `read` (called with `directory`/dataset.json
// and then with `directory`/NAME for each file the manifest names): a data set held in
// memory or in an archive.
absl::StatusOr<Dataset> ReadDataset(const std::string& directory, const FileReader& read);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_DATASET_READER_H_
