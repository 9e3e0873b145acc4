// Typed access to the fields of a JSON document, with errors naming the location (a file,
// or file:line) and the field path: "<location>: field '<path.key>': <what>". Shared by the
// data-set manifest reader and the submaps.jsonl reader. Private to subslam::io.
#ifndef SUBSLAM_IO_SRC_JSON_FIELDS_H_
#define SUBSLAM_IO_SRC_JSON_FIELDS_H_

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace subslam::io {

class JsonFields {
 public:
  using json = nlohmann::json;

  explicit JsonFields(std::string location) : location_(std::move(location)) {}

  absl::Status Error(const std::string& field, const std::string& what) const {
    return absl::InvalidArgumentError(absl::StrCat(location_, ": field '", field, "': ", what));
  }

  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : absl::StrCat(path, ".", key);
  }

  // Rejects keys of `object` that are not in `allowed`.
  absl::Status CheckKeys(const json& object, const std::string& path, const std::set<std::string>& allowed) const {
    for (const auto& [key, value] : object.items()) {
      if (!allowed.contains(key)) {
        return Error(Join(path, key), absl::StrCat("unknown key (allowed: ", absl::StrJoin(allowed, ", "), ")"));
      }
    }
    return absl::OkStatus();
  }

  // A finite number; `fallback` is used when the key is absent (nullopt: required).
  absl::StatusOr<double> Number(const json& parent, const std::string& path, const std::string& key,
                                std::optional<double> fallback = std::nullopt) const {
    const std::string field = Join(path, key);
    if (!parent.contains(key)) {
      if (fallback.has_value()) return *fallback;
      return Error(field, "missing");
    }
    const json& v = parent.at(key);
    if (!v.is_number()) return Error(field, absl::StrCat("expected a number, got ", v.dump()));
    const double d = v.get<double>();
    if (!std::isfinite(d)) return Error(field, "not finite");
    return d;
  }

  absl::StatusOr<int> Integer(const json& parent, const std::string& path, const std::string& key) const {
    const std::string field = Join(path, key);
    if (!parent.contains(key)) return Error(field, "missing");
    const json& v = parent.at(key);
    if (!v.is_number_integer()) return Error(field, absl::StrCat("expected an integer, got ", v.dump()));
    return v.get<int>();
  }

  // An array of finite numbers, of length n when given.
  absl::StatusOr<std::vector<double>> Numbers(const json& parent, const std::string& path, const std::string& key,
                                              std::optional<size_t> n = std::nullopt) const {
    const std::string field = Join(path, key);
    if (!parent.contains(key)) return Error(field, "missing");
    const json& v = parent.at(key);
    if (!v.is_array() || (n.has_value() && v.size() != *n)) {
      return Error(field, n.has_value() ? absl::StrCat("expected an array of ", *n, " numbers, got ", v.dump())
                                        : std::string("expected an array of numbers"));
    }
    std::vector<double> out;
    out.reserve(v.size());
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
        return Error(absl::StrCat(field, "[", i, "]"), absl::StrCat("expected a finite number, got ", v[i].dump()));
      }
      out.push_back(v[i].get<double>());
    }
    return out;
  }

 private:
  std::string location_;
};

// `text` (the contents of `path`) as a JSON document; a syntax error names path:line.
inline absl::StatusOr<nlohmann::json> ParseJsonDocument(const std::string& path, const std::string& text) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false, /*ignore_comments=*/false);
  if (!j.is_discarded()) return j;
  // Re-parse with exceptions only to learn where the syntax error is.
  try {
    const nlohmann::json unused = nlohmann::json::parse(text);
    (void)unused;
  } catch (const nlohmann::json::parse_error& e) {
    const size_t byte = std::min<size_t>(e.byte, text.size());
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + byte, '\n'));
    return absl::InvalidArgumentError(absl::StrCat(path, ":", line, ": invalid JSON: ", e.what()));
  } catch (const nlohmann::json::exception& e) {  // e.g. a number beyond a double's range
    return absl::InvalidArgumentError(absl::StrCat(path, ": invalid JSON: ", e.what()));
  }
  return absl::InvalidArgumentError(absl::StrCat(path, ": invalid JSON"));
}

}  // namespace subslam::io

#endif  // SUBSLAM_IO_SRC_JSON_FIELDS_H_
