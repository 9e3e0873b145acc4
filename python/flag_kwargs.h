// Keyword arguments as the tool's flags: a Python job's options are the flags of the same
// `subslam` command, named without the dashes (`particles=200` is `--particles=200`), so
// that a job from Python is the tool's job, checked by the same rules with the same
// messages.
//
//   {
//     FlagScope scope("run", kwargs);           // sets the flags; raises on a bad keyword
//     request = tool::RunRequestFromFlags();    // reads them
//   }                                           // the flags are restored here
//
// The flags are process-wide, so a scope holds a process-wide lock while it lives: build the
// request inside it and run the job after it (with the GIL released), and jobs on separate
// threads run in parallel.
#ifndef SUBSLAM_PYTHON_FLAG_KWARGS_H_
#define SUBSLAM_PYTHON_FLAG_KWARGS_H_

#include <pybind11/pybind11.h>

#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace subslam::python {

class FlagScope {
 public:
  // Sets every keyword as the flag of that name for `command` (run, join, solve, study,
  // calibrate, simulate). Keywords in `excluded` are left to the caller (the binding takes
  // them as arguments of its own). Raises TypeError for a keyword that no invocation of the
  // command reads, ValueError for a value the flag does not parse; `config="report.json"`
  // sets every flag the report recorded that no keyword sets (`subslam run --config`).
  FlagScope(const std::string& command, const pybind11::kwargs& kwargs, const std::vector<std::string>& excluded = {});
  ~FlagScope();
  FlagScope(const FlagScope&) = delete;
  FlagScope& operator=(const FlagScope&) = delete;

  // report.json's "invocation": the equivalent command line and every flag's value, so that
  // `subslam COMMAND --config report.json` repeats a job run from Python.
  nlohmann::json Invocation() const;

 private:
  // Every program flag's value when the scope began, restored when it ends (absl::FlagSaver
  // would do the same, but logs each restored flag on stderr). A member of its own, so that
  // the flags are restored when the constructor raises too.
  class Restorer {
   public:
    Restorer();
    ~Restorer();

   private:
    std::vector<std::pair<std::string, std::string>> saved_;
  };

  std::unique_lock<std::mutex> lock_;
  Restorer restorer_;
  std::string command_;
  std::vector<std::string> command_line_;
};

// A keyword's value as a flag's text: bool as true/false, numbers as Python's repr (which
// round-trips a float), None as empty (an optional flag unset), a list as comma-separated.
std::string FlagText(const pybind11::handle& value);

}  // namespace subslam::python

#endif  // SUBSLAM_PYTHON_FLAG_KWARGS_H_
