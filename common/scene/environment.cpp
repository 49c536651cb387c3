#include "common/scene/environment.h"

#include <algorithm>
#include <cmath>

#include "common/core/error.h"
#include "common/image/image_file.h"
#include "common/scene/punctual_light.h"
#include "common/scene/scene_budget.h"
#include "common/scene/scene_reference.h"

namespace pf {

Vec3 Environment::ToLocal(const Vec3& world) const {
  if (rotation_deg == 0.0f) return world;
  // The inverse of ToWorld: a rotation by −α about +Y.
  const double a = double(rotation_deg) * (kPi / 180.0);
  const float c = float(std::cos(a)), s = float(std::sin(a));
  return Vec3(c * world.x - s * world.z, world.y, s * world.x + c * world.z);
}

Vec3 Environment::ToWorld(const Vec3& local) const {
  if (rotation_deg == 0.0f) return local;
  // Right-handed rotation by α about +Y: x' = x cos α + z sin α, z' = −x sin α + z cos α.
  const double a = double(rotation_deg) * (kPi / 180.0);
  const float c = float(std::cos(a)), s = float(std::sin(a));
  return Vec3(c * local.x + s * local.z, local.y, -s * local.x + c * local.z);
}

float Environment::RowZ(int i) const {
  const int h = height();
  if (i <= 0) return 1.0f;
  if (i >= h) return -1.0f;
  return float(std::cos(double(i) * double(kPi) / double(h)));
}

void Environment::Cell(const Vec3& d, int* row, int* col) const {
  const int h = height(), w = width();
  const float y = std::clamp(d.y, -1.0f, 1.0f);
  int r = std::clamp(int(std::acos(double(y)) / double(kPi) * h), 0, h - 1);
  // acos rounds: settle the row on the boundaries themselves (z[r+1] < y ≤ z[r]).
  if (r > 0 && y > RowZ(r)) --r;
  if (r < h - 1 && !(y > RowZ(r + 1))) ++r;
  const double phi = std::atan2(double(d.x), -double(d.z));  // [−π, π]
  *row = r;
  *col = std::clamp(int((phi + double(kPi)) / (2.0 * double(kPi)) * w), 0, w - 1);
}

Vec3 Environment::Direction(float z, int col, float dv) const {
  const double phi = 2.0 * double(kPi) * (double(col) + double(dv)) / double(width()) - double(kPi);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return Vec3(r * float(std::sin(phi)), z, -r * float(std::cos(phi)));
}

Rgb Environment::Radiance(const Vec3& wi) const {
  if (!image) return color * strength;
  int row, col;
  Cell(ToLocal(wi), &row, &col);
  return Texel(row, col);
}

void LoadEnvironmentImage(const std::filesystem::path& manifest, const std::filesystem::path& root,
                          const std::filesystem::path& folder, Environment* environment,
                          PixelAllowance* texels) {
  if (environment->file.empty()) return;
  std::filesystem::path resolved;
  const std::string problem = SceneReferenceProblem(root, folder, environment->file, &resolved);
  if (!problem.empty())
    throw InputError(SourceLocation{manifest.string(), 0},
                     "key 'environment.file': " + QuoteReference(environment->file) + " " + problem);
  PixelAllowance own(SceneBudget{}.max_texels);
  auto image = std::make_shared<const Image>(ReadLinearImage(resolved, texels != nullptr ? texels : &own));
  float brightest = 0.0f;
  for (const Rgb& c : image->pixels()) brightest = std::max(brightest, c.Max());
  const auto fail = [&](const std::string& reason) {
    throw InputError(SourceLocation{manifest.string(), 0},
                     "key 'environment.file': " + QuoteReference(environment->file) + " " + reason);
  };
  if (!(brightest > 0.0f)) fail("is black (a light that emits nothing)");
  // Every power (π·R²·∫L dω) must stay a finite float, like a punctual light's.
  if (!(double(brightest) * environment->strength <= double(kMaxLightIntensity)))
    fail("x strength exceeds " + std::to_string(kMaxLightIntensity) + " in a channel");
  environment->image = std::move(image);
}

}  // namespace pf
