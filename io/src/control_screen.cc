#include "subslam/io/control_screen.h"

#include <algorithm>
#include <cmath>

namespace subslam::io {

namespace {

// Channel c of the control noise σ at control value u (models::ControlNoise).
double Sigma(const models::ControlNoise& noise, int c, double u) {
  return c == 0 ? noise.sigma_u0 + noise.scale_u0 * std::abs(u) : noise.sigma_u1 + noise.scale_u1 * std::abs(u);
}

// Of an even count: the mean of the middle two.
double Median(std::vector<double>& v) {
  const size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + h, v.end());
  const double upper = v[h];
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + h));
}

}  // namespace

ControlScreen::ControlScreen(const models::ControlNoise& noise, const InputScreeningOptions& options)
    : noise_(noise), options_(options) {}

std::optional<ControlRecord> ControlScreen::Push(const ControlRecord& record) {
  const int w = InputScreeningOptions::kSpikeWindow;
  held_.push_back(record);
  ++pushed_;
  if (static_cast<int>(held_.size()) <= w) return std::nullopt;
  if (static_cast<int>(held_.size()) < 2 * w + 1) {  // one of the first w records: unjudged
    return held_[held_.size() - 1 - w];
  }
  // held_: the w records before the one judged (held_[w]), it, and the w after it, as read.
  ControlRecord out = held_[w];
  std::vector<double>& around = around_;
  std::vector<double>& deviations = deviations_;
  around.resize(2 * w);
  deviations.resize(2 * w);
  bool spike = false;
  for (int c = 0; c < 2; ++c) {
    for (int i = 0; i < w; ++i) {
      around[i] = held_[i].u[c];
      around[w + i] = held_[w + 1 + i].u[c];
    }
    const double m = Median(around);
    for (int i = 0; i < 2 * w; ++i) deviations[i] = std::abs(around[i] - m);
    // The neighbours' own spread (as a σ: 1.4826 × their median absolute deviation) or
    // the noise model's σ, whichever is larger.
    const double scale = std::max(Sigma(noise_, c, m), 1.4826 * Median(deviations));
    if (std::abs(held_[w].u[c] - m) > options_.control_spike_sigmas * scale) {
      spike = true;
      if (options_.replace_control_spikes) out.u[c] = m;
    }
  }
  control_spikes_ += spike ? 1 : 0;
  held_.pop_front();
  return out;
}

std::vector<ControlRecord> ControlScreen::Flush() {
  // Returned so far: all but the last w pushed (the first of them unjudged).
  const long w = InputScreeningOptions::kSpikeWindow;
  const size_t returned_held = static_cast<size_t>(std::clamp(pushed_ - w, 0L, w));
  std::vector<ControlRecord> out(held_.begin() + static_cast<long>(std::min(returned_held, held_.size())), held_.end());
  held_.clear();
  pushed_ = 0;
  return out;
}

}  // namespace subslam::io
