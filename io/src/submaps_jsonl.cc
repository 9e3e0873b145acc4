#include "subslam/io/submaps_jsonl.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "json_fields.h"

namespace subslam::io {
namespace {

using nlohmann::json;

json NumberOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json ToJson(const LocalSubmap& s) {
  json state = json::array(), cov = json::array(), landmarks = json::array();
  for (Eigen::Index i = 0; i < s.mean.size(); ++i) state.push_back(s.mean[i]);
  for (Eigen::Index r = 0; r < s.covariance.rows(); ++r) {
    for (Eigen::Index c = 0; c < s.covariance.cols(); ++c) cov.push_back(s.covariance(r, c));
  }
  for (const LocalSubmapLandmark& l : s.landmarks) {
    json entry = {{"local_id", l.local_id},
                  {"signature", NumberOrNull(l.signature)},
                  {"existence", l.existence},
                  {"truth_id", l.truth_id ? json(*l.truth_id) : json(nullptr)}};
    if (l.truth_landmarks) entry["truth_landmarks"] = *l.truth_landmarks;
    if (!l.truth_ids.empty()) entry["truth_ids"] = l.truth_ids;
    landmarks.push_back(std::move(entry));
  }
  json out = {{"id", s.id},     {"t_start", s.t_start}, {"t_end", s.t_end},
              {"state", state}, {"cov", cov},           {"landmarks", landmarks}};
  if (s.covariance_repairs > 0) out["covariance_repairs"] = s.covariance_repairs;
  return out;
}

// A feature's true ids (evaluation only): ascending, distinct, agreeing with its majority
// truth_id and its count of true landmarks.
absl::Status TruthIdsFromJson(const json& l, const JsonFields& r, const std::string& path, LocalSubmapLandmark* out) {
  const json& ids = l.at("truth_ids");
  const std::string field = path + ".truth_ids";
  if (!ids.is_array()) return r.Error(field, absl::StrCat("expected an array of true ids, got ", ids.dump()));
  for (size_t k = 0; k < ids.size(); ++k) {
    const bool in_range = ids[k].is_number_unsigned() ? ids[k].get<unsigned long long>() <= INT_MAX
                                                      : ids[k].is_number_integer() && ids[k].get<long long>() >= 0;
    if (!in_range) {
      return r.Error(absl::StrCat(field, "[", k, "]"),
                     absl::StrCat("expected an integer id in [0, ", INT_MAX, "], got ", ids[k].dump()));
    }
    const int id = ids[k].get<int>();
    if (!out->truth_ids.empty() && id <= out->truth_ids.back()) {
      return r.Error(absl::StrCat(field, "[", k, "]"), "ids must be ascending and distinct");
    }
    out->truth_ids.push_back(id);
  }
  // They must agree with the feature's majority id and its count of true landmarks.
  if (out->truth_id.has_value() && *out->truth_id >= 0 && !out->truth_ids.empty() &&
      !std::binary_search(out->truth_ids.begin(), out->truth_ids.end(), *out->truth_id)) {
    return r.Error(field, absl::StrCat("does not contain truth_id ", *out->truth_id));
  }
  if (out->truth_landmarks.has_value() && *out->truth_landmarks != static_cast<int>(out->truth_ids.size())) {
    return r.Error(
        field, absl::StrCat("lists ", out->truth_ids.size(), " ids but truth_landmarks is ", *out->truth_landmarks));
  }
  return absl::OkStatus();
}

// Landmark `path` of a local map.
absl::StatusOr<LocalSubmapLandmark> LandmarkFromJson(const json& l, const JsonFields& r, const std::string& path) {
  if (!l.is_object()) return r.Error(path, "expected an object");
  if (auto st =
          r.CheckKeys(l, path, {"local_id", "signature", "existence", "truth_id", "truth_landmarks", "truth_ids"});
      !st.ok()) {
    return st;
  }
  LocalSubmapLandmark out;
  auto local_id = r.Integer(l, path, "local_id");
  if (!local_id.ok()) return local_id.status();
  out.local_id = *local_id;
  auto existence = r.Number(l, path, "existence");
  if (!existence.ok()) return existence.status();
  if (*existence < 0.0 || *existence > 1.0) {
    return r.Error(path + ".existence", absl::StrCat("must be in [0, 1], got ", *existence));
  }
  out.existence = *existence;
  if (l.contains("signature") && !l.at("signature").is_null()) {
    auto sig = r.Number(l, path, "signature");
    if (!sig.ok()) return sig.status();
    out.signature = *sig;
  }
  if (l.contains("truth_id") && !l.at("truth_id").is_null()) {
    auto truth = r.Integer(l, path, "truth_id");
    if (!truth.ok()) return truth.status();
    if (*truth < -1) return r.Error(path + ".truth_id", "must be >= -1 (-1: false alarm)");
    out.truth_id = *truth;
  }
  if (l.contains("truth_landmarks") && !l.at("truth_landmarks").is_null()) {
    auto count = r.Integer(l, path, "truth_landmarks");
    if (!count.ok()) return count.status();
    if (*count < 0) return r.Error(path + ".truth_landmarks", "must be >= 0");
    out.truth_landmarks = *count;
  }
  if (l.contains("truth_ids") && !l.at("truth_ids").is_null()) {
    if (absl::Status st = TruthIdsFromJson(l, r, path, &out); !st.ok()) return st;
  }
  return out;
}

// `previous_t_end`: where a map without times is put (see ReadSubmapsJsonl).
absl::StatusOr<LocalSubmap> FromJson(const json& j, const JsonFields& r, double previous_t_end) {
  if (!j.is_object()) return r.Error("(line)", "expected a JSON object");
  if (auto s = r.CheckKeys(j, "", {"id", "t_start", "t_end", "state", "cov", "landmarks", "covariance_repairs"});
      !s.ok()) {
    return s;
  }
  LocalSubmap s;
  auto id = r.Integer(j, "", "id");
  if (!id.ok()) return id.status();
  s.id = *id;
  // Times are optional (absent or null, as other tools write local maps): such a map
  // takes the zero-length span at the previous map's end. Both or neither.
  const auto given = [&j](const char* key) { return j.contains(key) && !j.at(key).is_null(); };
  if (given("t_start") != given("t_end")) {
    return r.Error(given("t_start") ? "t_end" : "t_start", "missing while the other time is given");
  }
  if (given("t_start")) {
    auto t0 = r.Number(j, "", "t_start");
    if (!t0.ok()) return t0.status();
    auto t1 = r.Number(j, "", "t_end");
    if (!t1.ok()) return t1.status();
    s.t_start = *t0;
    s.t_end = *t1;
    if (s.t_end < s.t_start) return r.Error("t_end", "is before t_start");
  } else {
    s.t_start = s.t_end = previous_t_end;
  }
  if (j.contains("covariance_repairs")) {
    auto repairs = r.Integer(j, "", "covariance_repairs");
    if (!repairs.ok()) return repairs.status();
    if (*repairs < 0) return r.Error("covariance_repairs", "must be >= 0");
    s.covariance_repairs = *repairs;
  }
  if (!j.contains("landmarks")) return r.Error("landmarks", "missing");
  const json& landmarks = j.at("landmarks");
  if (!landmarks.is_array()) return r.Error("landmarks", "expected an array");
  for (size_t i = 0; i < landmarks.size(); ++i) {
    auto landmark = LandmarkFromJson(landmarks[i], r, absl::StrCat("landmarks[", i, "]"));
    if (!landmark.ok()) return landmark.status();
    s.landmarks.push_back(*std::move(landmark));
  }
  const size_t n = 3 + 2 * s.landmarks.size();
  auto state = r.Numbers(j, "", "state");
  if (!state.ok()) return state.status();
  if (state->size() != n) {
    return r.Error("state", absl::StrCat("has ", state->size(), " numbers, expected 3 + 2 × ", s.landmarks.size(),
                                         " landmarks = ", n));
  }
  auto cov = r.Numbers(j, "", "cov");
  if (!cov.ok()) return cov.status();
  if (cov->size() != n * n) {
    return r.Error("cov", absl::StrCat("has ", cov->size(), " numbers, expected ", n * n));
  }
  s.mean = Eigen::Map<const Eigen::VectorXd>(state->data(), static_cast<Eigen::Index>(n));
  s.covariance = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      cov->data(), static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  s.RegularizeDegenerateCovariance();  // a documented rule, counted in covariance_repairs
  if (absl::Status valid = s.Validate(); !valid.ok()) return r.Error("(local map)", std::string(valid.message()));
  return s;
}

}  // namespace

absl::Status WriteSubmapsJsonl(const std::string& path, const std::vector<LocalSubmap>& submaps) {
  std::ofstream out(path);
  if (!out) return absl::UnavailableError(absl::StrCat(path, ": cannot open for writing"));
  for (const LocalSubmap& s : submaps) out << ToJson(s).dump() << '\n';
  out.flush();
  if (!out) return absl::DataLossError(absl::StrCat(path, ": write failed"));
  return absl::OkStatus();
}

absl::StatusOr<std::vector<LocalSubmap>> ParseSubmapsJsonl(const std::string& text, const std::string& source) {
  std::vector<LocalSubmap> out;
  int line = 0;
  for (size_t start = 0; start < text.size();) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string line_text = text.substr(start, end - start);
    start = end + 1;
    ++line;
    if (line_text.find_first_not_of(" \t\r") == std::string::npos) continue;
    const JsonFields reader(absl::StrCat(source, ":", line));
    json j;
    try {
      j = json::parse(line_text);
    } catch (const json::exception& e) {  // a syntax error, or a number beyond a double's range
      return reader.Error("(line)", absl::StrCat("invalid JSON: ", e.what()));
    }
    absl::StatusOr<LocalSubmap> s = FromJson(j, reader, out.empty() ? 0.0 : out.back().t_end);
    if (!s.ok()) return s.status();
    if (!out.empty() && s->id <= out.back().id) {
      return reader.Error("id", absl::StrCat("ids must increase (", s->id, " after ", out.back().id, ")"));
    }
    out.push_back(*std::move(s));
  }
  if (out.empty()) return absl::InvalidArgumentError(absl::StrCat(source, ": no local maps (empty file)"));
  return out;
}

absl::StatusOr<std::vector<LocalSubmap>> ReadSubmapsJsonl(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open"));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return absl::DataLossError(absl::StrCat(path, ": read error"));
  return ParseSubmapsJsonl(buffer.str(), path);
}

}  // namespace subslam::io
