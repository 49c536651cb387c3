#include "common/lights/light_choice.h"

#include <algorithm>
#include <cmath>

namespace pf {

LightChoice::LightChoice(const LightSampler& lights, float uniform_fraction) : lights_(&lights) {
  const size_t n = lights.num_lights();
  double total = 0;
  for (size_t i = 0; i < n; ++i) total += lights.light_power(i).Luminance();
  const float beta = std::clamp(uniform_fraction, 0.0f, 0.999f);
  double acc = 0;
  for (size_t i = 0; i < n; ++i) {
    const double by_power = total > 0 ? lights.light_power(i).Luminance() / total : 1.0 / double(n);
    acc += (1.0 - beta) * by_power + beta / double(n);
    cdf_.push_back(float(acc));
  }
  if (!cdf_.empty()) cdf_.back() = 1.0f;
  // The probability of light i is the width of its stratum of the float CDF that Choose
  // searches, not p_i itself: the weights then match the choice exactly.
  for (size_t i = 0; i < n; ++i) prob_.push_back(cdf_[i] - (i > 0 ? cdf_[i - 1] : 0.0f));
  if (const EnvironmentLight* environment = lights.environment())
    environment_light_ = lights.LightIndex(environment->light());
}

LightChoice::Choice LightChoice::Choose(float u) const {
  Choice c;
  c.light = std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u) - cdf_.begin(), cdf_.size() - 1);
  c.probability = prob_[c.light];
  if (c.probability > 0.0f) {
    const float low = c.light > 0 ? cdf_[c.light - 1] : 0.0f;
    c.u = std::clamp((u - low) / c.probability, 0.0f, std::nextafter(1.0f, 0.0f));
  }
  return c;
}

float LightChoice::PdfArea(uint32_t tri) const {
  const size_t light = lights_->LightOfTriangle(tri);
  return light < prob_.size() ? prob_[light] * lights_->PdfAreaWithinLight(tri) : 0.0f;
}

float LightChoice::PdfEnvironment(const Vec3& wi) const {
  const EnvironmentLight* environment = lights_->environment();
  return environment ? prob_[environment_light_] * environment->Pdf(wi) : 0.0f;
}

}  // namespace pf
