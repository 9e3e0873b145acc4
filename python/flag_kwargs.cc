#include "flag_kwargs.h"

#include <algorithm>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "command_flags.h"
#include "invocation.h"

namespace py = pybind11;

namespace subslam::python {
namespace {

std::mutex& FlagsMutex() {
  static auto* mutex = new std::mutex;
  return *mutex;
}

// Notes the flags a command line names (cli::FlagGiven): a keyword given at its flag's
// default still counts as given, as on the command line.
void NoteGiven(const std::vector<std::string>& command_line) {
  std::vector<char*> argv;
  for (const std::string& arg : command_line) argv.push_back(const_cast<char*>(arg.c_str()));
  cli::NoteFlagsGiven(static_cast<int>(argv.size()), argv.data());
}

}  // namespace

std::string FlagText(const py::handle& value) {
  if (value.is_none()) return "";
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    std::vector<std::string> items;
    for (const py::handle item : value) items.push_back(FlagText(item));
    return absl::StrJoin(items, ",");
  }
  if (py::hasattr(value, "__fspath__")) return py::str(value.attr("__fspath__")()).cast<std::string>();
  return py::repr(value).cast<std::string>();  // int, float (repr round-trips), numpy scalars
}

FlagScope::FlagScope(const std::string& command, const py::kwargs& kwargs, const std::vector<std::string>& excluded)
    : lock_(FlagsMutex()), command_(command) {
  const std::vector<std::string> program = cli::ProgramFlagNames();  // sorted
  command_line_ = {"subslam", command};
  std::string config;
  for (const auto& [key, value] : kwargs) {
    const std::string name = key.cast<std::string>();
    if (std::find(excluded.begin(), excluded.end(), name) != excluded.end()) continue;
    if (name == "config" && (command == "run" || command == "join" || command == "solve")) {
      config = FlagText(value);
      continue;
    }
    absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    if (flag == nullptr || !std::binary_search(program.begin(), program.end(), name) ||
        !cli::CommandMayReadFlag(name, command)) {
      throw py::type_error(absl::StrCat(command, "() got an unexpected keyword argument '", name, "' (`subslam help ",
                                        command, "` lists the options, without their dashes)"));
    }
    const std::string text = FlagText(value);
    std::string error;
    if (!flag->ParseFrom(text, &error)) {
      throw py::value_error(
          absl::StrCat(command, "(): keyword ", name, "=", py::repr(value).cast<std::string>(), ": ", error));
    }
    command_line_.push_back(absl::StrCat("--", name, "=", text));
  }
  NoteGiven(command_line_);
  if (!config.empty()) {
    command_line_.push_back(absl::StrCat("--config=", config));
    if (absl::Status s = cli::ApplyRecordedFlags(config, command); !s.ok()) {
      throw py::value_error(absl::StrCat(command, "(): keyword config: ", s.message()));
    }
  }
}

FlagScope::~FlagScope() = default;

FlagScope::Restorer::Restorer() {
  for (const std::string& name : cli::ProgramFlagNames()) {
    saved_.emplace_back(name, absl::FindCommandLineFlag(name)->CurrentValue());
  }
}

FlagScope::Restorer::~Restorer() {
  for (const auto& [name, value] : saved_) {
    absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    std::string error;
    if (flag->CurrentValue() != value) flag->ParseFrom(value, &error);  // a value it printed itself
  }
  NoteGiven({"subslam"});
}

nlohmann::json FlagScope::Invocation() const {
  std::vector<char*> argv;
  for (const std::string& arg : command_line_) argv.push_back(const_cast<char*>(arg.c_str()));
  return cli::InvocationJson(static_cast<int>(argv.size()), argv.data(), command_);
}

}  // namespace subslam::python
