#include "common/lights/environment_light.h"

#include <algorithm>
#include <cmath>

#include "common/core/error.h"

namespace pf {
namespace {

// cdf[0..n] from non-negative weights; uniform when they sum to 0 (a black row is never chosen:
// its marginal weight is 0, but its conditional stays well defined).
void BuildCdf(const std::vector<double>& weights, float* cdf) {
  const size_t n = weights.size();
  double total = 0;
  for (double w : weights) total += w;
  cdf[0] = 0.0f;
  double acc = 0;
  for (size_t i = 0; i < n; ++i) {
    acc += weights[i];
    cdf[i + 1] = total > 0 ? float(acc / total) : float(double(i + 1) / double(n));
  }
  cdf[n] = 1.0f;
}

}  // namespace

EnvironmentLight::EnvironmentLight(const Environment& environment, const Vec3& centre, float radius)
    : environment_(environment),
      centre_(centre),
      radius_(radius),
      width_(environment.width()),
      height_(environment.height()) {
  row_cdf_.resize(size_t(height_) + 1);
  column_cdf_.resize(size_t(height_) * (size_t(width_) + 1));
  std::vector<double> row_weights(static_cast<size_t>(height_)), column_weights(static_cast<size_t>(width_));
  double integrated[3] = {0, 0, 0};
  for (int i = 0; i < height_; ++i) {
    const double cell = double(environment_.CellSolidAngle(i));
    double row = 0;
    for (int j = 0; j < width_; ++j) {
      const Rgb l = environment_.Texel(i, j);
      column_weights[size_t(j)] = double(l.Luminance());
      row += column_weights[size_t(j)];
      for (int c = 0; c < 3; ++c) integrated[c] += double(l[c]) * cell;
    }
    row_weights[size_t(i)] = row * cell;
    BuildCdf(column_weights, &column_cdf_[size_t(i) * (size_t(width_) + 1)]);
  }
  BuildCdf(row_weights, row_cdf_.data());
  integrated_ = Rgb(float(integrated[0]), float(integrated[1]), float(integrated[2]));
  power_ = integrated_ * (kPi * radius * radius);
  if (!(integrated_.Luminance() > 0.0f) || !power_.IsFinite())
    throw InputError("environment" +
                     (environment.file.empty() ? std::string() : " '" + environment.file + "'") +
                     ": its power is not a finite positive number (is the image black?)");
}

int EnvironmentLight::Piece(const float* cdf, int n, float u, float* remapped) {
  // The piece i with cdf[i] ≤ u < cdf[i+1]; empty pieces (cdf[i] = cdf[i+1]) are never found.
  const int i = std::clamp(int(std::upper_bound(cdf + 1, cdf + n + 1, u) - (cdf + 1)), 0, n - 1);
  const float width = cdf[i + 1] - cdf[i];
  *remapped = width > 0.0f ? std::clamp((u - cdf[i]) / width, 0.0f, 0x1.fffffep-1f) : 0.0f;
  return i;
}

EnvironmentLight::DirectionSample EnvironmentLight::Sample(float u1, float u2) const {
  float du, dv;
  const int row = Piece(row_cdf_.data(), height_, u1, &du);
  const int col = Piece(&column_cdf_[size_t(row) * (size_t(width_) + 1)], width_, u2, &dv);
  const float z_top = environment_.RowZ(row), z_bottom = environment_.RowZ(row + 1);
  const float z = std::clamp(z_top - du * (z_top - z_bottom), z_bottom, z_top);
  DirectionSample s;
  s.wi = environment_.ToWorld(environment_.Direction(z, col, dv));
  // The density and radiance of the direction as a ray leaving the scene there sees them: MIS
  // weights of both strategies then use one value (a cell boundary is a set of measure zero).
  s.pdf = Pdf(s.wi);
  s.radiance = environment_.Radiance(s.wi);
  return s;
}

float EnvironmentLight::Pdf(const Vec3& wi) const {
  int row, col;
  environment_.Cell(environment_.ToLocal(wi), &row, &col);
  const float* cdf = &column_cdf_[size_t(row) * (size_t(width_) + 1)];
  const float p = (row_cdf_[size_t(row) + 1] - row_cdf_[size_t(row)]) * (cdf[col + 1] - cdf[col]);
  return p > 0.0f ? p / environment_.CellSolidAngle(row) : 0.0f;
}

}  // namespace pf
