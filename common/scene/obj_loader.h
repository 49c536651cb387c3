#pragma once
// Wavefront OBJ/MTL → SceneDescription, through tinyobjloader (ObjReader, triangulated).
//
// Geometry
//   * Polygons are triangulated by tinyobjloader. Vertices are shared per (position, normal)
//     pair. Per-vertex normals (`vn`) are used when a face corner has one (normalised); corners
//     without one get the zero normal ("use the geometric normal", scene.h). Texture
//     coordinates and vertex colours are ignored.
//   * Every OBJ *shape* (`g`/`o` group) that has triangles with an emissive material is one
//     light: all its emissive triangles share one light id, numbered in file order.
//   * Faces without a material (no `usemtl`, or a name the MTL lacks) get a neutral grey
//     diffuse material "(default)" with ρd = 0.8, and a warning.
//
// MTL → Material (Ward's model, scene.h). Only these statements matter:
//   Kd        → ρd (diffuse reflectance).
//   Ks, Ns    → ρs with Ward roughness α = sqrt(2 / (Ns + 2)): the usual Phong → Beckmann
//               correspondence (a Phong lobe cos^Ns and a Beckmann/Ward lobe of RMS slope α
//               have about the same width when Ns = 2/α² − 2), so Ns 0 → α 1, Ns 10 → 0.41,
//               Ns 100 → 0.14, Ns 1000 → 0.045.
//               Ns ≥ kMirrorPhongExponent (1000), or `illum` 3 or 5 ("ray-traced reflection"),
//               make ρs a perfect mirror (α = 0).
//   Ke        → emission: Le, the emitted radiance in W/(m²·sr) per channel, leaving the
//               front face only (the side the polygon's vertex order faces, counter-clockwise
//               = front). A light's power is therefore π·Le·area.
//   illum 4/6/7 → glass, a Fresnel dielectric: τs = Tf (or 1 when Tf is absent/black),
//               ior = Ni. The BSDF ignores ρd and ρs for such a material (its reflection is
//               Fresnel's), so the loader sets them to zero, warning when Kd or Ks was given.
//               Ni ≤ 1 is kept, with a warning (the surface then transmits without bending).
//   d < 1 (or Tr > 0) on a non-glass material → "dissolve": a see-through surface without
//               refraction: τs = 1 − d, ior = 1, and ρd, ρs are scaled by d (a d-fraction of
//               the surface is opaque).
//   Tf on an opaque material (illum not 4/6/7, d = 1) is ignored with a warning, unless it
//               is white (many exporters write `Tf 1 1 1` on everything). A manifest can turn
//               such a material into glass (docs/scene-manifest.md, "materials").
//   Ni        → ior for glass only; opaque and dissolve materials get ior = 1 (OBJ exporters
//               write Ni on every material, meaningless without transmission).
//   map_Kd    → an image texture multiplying Kd (sRGB-decoded); map_Ke → one multiplying Ke
//               (sRGB; ignored without Ke); map_d → an alpha mask: the
//               surface is cut out, for every ray, where the map (its alpha channel, or its grey
//               value without one; linear) is below kObjAlphaCutoff. `d` keeps its meaning above
//               (dissolve) beside map_d. Both ignored on an emitter (warned).
//   Ka, other maps, `illum` 0/1/2/8/9, PBR extensions (Pr, Pm, ...) are ignored.
//   If ρd + ρs + τs > 1 in a channel, all three are scaled down to sum to 1 there, with a
//   warning (energy conservation).
//
// Errors (InputError): missing/unreadable file, tinyobjloader parse errors (its message, with
// the line when it names one), faces that reference vertices or normals that do not exist
// (with the line of the first such face), non-finite coordinates.

#include <filesystem>
#include <string>
#include <vector>

#include "common/core/math.h"
#include "common/scene/scene.h"
#include "common/scene/scene_budget.h"

namespace pf {

class PixelAllowance;  // common/image/image_file.h

// `mtllib` files resolve only inside `root` (scene_reference.h; empty = the OBJ's own folder):
// a reference outside it is an InputError naming the file and line; a missing file inside it
// is a warning (its faces get the default material).
// Before tinyobjloader stores anything, the statements are counted (`f` corners − 2 triangles,
// `v`/`vn`/`vt` vertices) and checked against `budget`: an InputError at the line where a count
// crosses one (scene_budget.h). `counts`, if set, receives them.
// Positions are read in double and stored in the scene's frame (scene_frame.h).
// `texels`: the load's image allowance, shared with its other images (null: budget.max_texels
// for this file's textures).
SceneDescription LoadObj(const std::filesystem::path& path, const std::filesystem::path& root = {},
                         const SceneBudget& budget = {}, SceneExpansion* counts = nullptr,
                         PixelAllowance* texels = nullptr);

// Phong exponents at or above this are treated as a perfect mirror.
inline constexpr float kMirrorPhongExponent = 1000.0f;
// map_d cuts the surface out where the map is below this (glTF's default alphaCutoff: a map of
// 0s and 1s, the usual foliage or fence mask, cuts where it is 0 whatever the filter's blend).
inline constexpr float kObjAlphaCutoff = 0.5f;

// Ward α for a Phong exponent: sqrt(2 / (Ns + 2)); negative Ns counts as 0. Returns 0
// (perfect mirror) for Ns >= kMirrorPhongExponent.
float WardAlphaFromPhongExponent(float ns);

// The MTL statements LoadObj reads, in a form independent of tinyobjloader (so that the
// mapping can be tested without files).
struct MtlParameters {
  std::string name;
  Rgb kd, ks, ke, tf;
  float ns = 1.0f;  // tinyobjloader's default
  float ni = 1.0f;
  float d = 1.0f;  // dissolve (1 = opaque); Tr is folded in as d = 1 − Tr
  int illum = 0;
};

// The mapping documented above. Warnings are appended as "material 'name': reason".
Material MaterialFromMtl(const MtlParameters& mtl, std::vector<std::string>* warnings);

// Scales ρd + ρs + τd + τs down to 1 in any channel where it exceeds 1. Returns true if it had
// to (the caller warns).
bool ClampEnergy(Material* material);

}  // namespace pf
