#pragma once
// The environment: radiance arriving from infinitely far away in every direction no surface
// blocks (docs/scene-manifest.md, "environment"; docs/renderer.md, "Environment light"). A
// constant colour, or an equirectangular (latitude-longitude) image.
//
// Directions, +Y up: θ the angle from +Y, φ = atan2(x, −z). Image row 0 is the top (θ = 0), the
// image's horizontal centre looks along −Z (where a default camera looks) and u grows towards
// +X, so the middle of the picture is what the camera sees, not its mirror image. `rotation`
// turns the environment by that many degrees about +Y (right-handed: 90° brings what was at −Z
// to −X). Texels are constant over their cell (nearest lookup): the light sampler's piecewise-
// constant distribution (lights/environment_light.h) is then exactly proportional to it.
//
// Cells: row i spans cos θ in [z[i+1], z[i]] with z[i] = cos(iπ/H) — equal steps in θ, the
// image's own rows — and column j spans φ in [2πj/W − π, 2π(j+1)/W − π].
// A constant colour is the 1x1 image of that colour.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "common/core/math.h"
#include "common/image/image.h"

namespace pf {

class PixelAllowance;  // common/image/image_file.h

struct Environment {
  std::string file;                      // the image as the manifest names it; empty: constant colour
  Rgb color{};                           // the constant radiance, W/(m²·sr) (before strength)
  float rotation_deg = 0.0f;             // about +Y
  float strength = 1.0f;                 // scales every texel
  std::shared_ptr<const Image> image{};  // the file's pixels (linear), shared by copies of the scene
  uint32_t light = 0;                    // the scene light id (scene.h)

  int width() const { return image ? image->width() : 1; }
  int height() const { return image ? image->height() : 1; }
  // Radiance of cell (row, col), strength applied.
  Rgb Texel(int row, int col) const { return (image ? image->at(col, row) : color) * strength; }
  // World direction ↔ the environment's own frame (rotation about +Y).
  Vec3 ToLocal(const Vec3& world) const;
  Vec3 ToWorld(const Vec3& local) const;
  // Radiance arriving from unit world direction `wi` (pointing away from the scene).
  Rgb Radiance(const Vec3& wi) const;

  // The cells (header comment): row boundary z[i] = cos(iπ/H), exactly 1 and −1 at the ends.
  float RowZ(int i) const;
  // The cell of a unit local direction d: the row with z[row+1] < d.y ≤ z[row], the column of φ.
  void Cell(const Vec3& d, int* row, int* col) const;
  // The local direction at cos θ = z and φ = 2π·(col + dv)/W − π.
  Vec3 Direction(float z, int col, float dv) const;
  // Solid angle of a cell of row i: (z[i] − z[i+1])·2π/W.
  float CellSolidAngle(int row) const { return (RowZ(row) - RowZ(row + 1)) * (2.0f * kPi / float(width())); }
};

// Reads environment->file (resolved against `folder`, confined to `root`: scene_reference.h) into
// environment->image; a constant colour is left alone. Problems are InputErrors naming the
// manifest and the key "environment.file", or the image file (image_file.h).
// The image is charged to `texels`, the load's allowance (null: SceneBudget::max_texels for it alone).
void LoadEnvironmentImage(const std::filesystem::path& manifest, const std::filesystem::path& root,
                          const std::filesystem::path& folder, Environment* environment,
                          PixelAllowance* texels = nullptr);

}  // namespace pf
