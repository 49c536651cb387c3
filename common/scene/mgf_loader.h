#pragma once
// MGF 2.0 loader: Greg Ward's Materials and Geometry Format, the scene format of Wald 1999.
// The spec is mgfdoc.tr ("The Materials and Geometry Format", LBL, version 1.1 text + `fh`);
// section numbers below refer to it (§2 basics, §3 entity reference, §6.1.1 colours).
//
// What it reads: every entity of the spec except `ies` (IES luminaires: warned and skipped).
//   #  o  xf  i  c cxy cspec cct cmix  m sides rd td ed rs ts ir  v p n  f fh sph cyl cone
//   ring torus prism, line continuation with a trailing backslash, LF / CR / CRLF line ends.
// Any line whose first word starts with '#' is a comment (the spec wants "# ", but the scenes
// we ship contain "#reception" and "#f v1 v2 v4"). Unknown entities are warnings, reported
// once per entity kind per file, as mgflib does.
//
// What it produces: a triangle soup (SceneDescription). Named contexts are captured by value
// when geometry is created (§2.1): redefining a material later does not change earlier faces.
//
// Tessellation rule (the spec leaves it to the application): with N = curve_segments, every full
// circle of a curved primitive is cut into N equal arcs: the rims of `cyl`/`cone`, the circles of
// `ring`, both the tube and the sweep circle of `torus`, and the sphere's parallels; a sphere has
// N/2 (at least 2) latitude bands between its poles. All vertices lie on the exact surface, so
// tessellated areas are a little smaller than the true ones (sphere, N=24: -1.4 %; N=12: -5.6 %).
// Curved primitives carry smooth per-vertex normals (cone apexes: one vertex per segment with
// the normal at the segment's middle); rings are flat. Orientation follows §3: `sph`/`cyl`/
// `cone` with positive radii face outwards, negative radii inwards; rings face along their
// centre's normal; a torus with a negative outer radius faces inwards; `prism` faces outwards
// for a positive length; `f`/`fh` keep the vertex order (right-hand rule = front). A transform
// with a mirror (negative determinant: an odd number of -mx/-my/-mz, or a negative -s) reverses
// face vertex order, so that mirrored closed objects stay outward-facing (as mgflib's xf "rev").
//
// Polygons (`f`, `fh`, prism end faces; up to 16384 vertices, the spec's 4096-character entity
// limit allows about 2000) are triangulated by ear clipping in their best-fit (Newell) plane;
// seams ("holes as concave polygons with coincident sides", §3 f) work because vertices
// coincident with an ear's corners never block it. `fh` holes are bridged to the outer contour
// (the seam an MGF author would have written) and then ear-clipped. Faces with fewer than three
// distinct vertices or zero area are warnings and skipped; self-intersecting faces are warned
// and triangulated approximately.
//
// Colour (§6.1.1): MGF colours are CIE 1931 (x,y) with the intensity carried by the material
// value. `cspec`/`cct` are integrated against the 1931 2° colour-matching functions (10 nm table,
// linearly interpolated); `cmix` sums the colours weighted by relative luminance (exact in XYZ).
// (x,y,Y) goes to linear RGB with the spec's XYZ->RGB matrix for its nominal CRT primaries
// (0.640,0.330) (0.290,0.600) (0.150,0.060) and equal-energy white (1/3,1/3), negative
// components clamped to 0 as in the spec's cie_rgb(). Equal-energy white maps to r=g=b.
// Like mgflib, `cxy` rejects only negative values and x + y > 1; a y below 1e-4 (no luminance,
// e.g. "cxy .4 0" in the hospital scene) is warned and replaced by neutral grey.
//   rd/rs/td/ts  -> value × RGB(colour, Y=1); rs/ts α -> roughness; ir n k -> ior = n (k warned).
//   ed (lm/m²)   -> Le = ed / (π · 179 lm/W) × RGB(colour, Y=1) in W/(m²·sr): a Lambertian emitter
//                   of exitance ed, in Radiance's "watts" (179 lm/W white efficacy, as mgf2rad).
//   If rd+rs+td+ts exceeds 1 in a channel, all four are scaled down so that the sum is 1 (warned).
//
// Lights: every emitting source primitive (one `f`, `sph`, `cyl`, ... and one array instance of
// it) is one light; its triangles share an id in triangle_light (0..num_lights-1).
//
// Positions are world coordinates in double until the whole file has been read; then the scene's
// frame is chosen from their bounds and they are stored as floats in it (scene_frame.h), so a
// model far from the origin keeps its shape.
//
// Budgets (scene_budget.h): before the first entity is executed, the loader computes what the
// file expands to — entities, array instances, triangles and vertices, from the entities of the
// file and of every file it includes and the nesting multipliers of their arrays — and refuses a
// file beyond MgfOptions::budget with an InputError at the line where the expansion crossed it
// (an `xf` or `i` with arrays, usually).
//
// Errors: malformed input throws InputError("file:line: reason"): bad numbers (including nan,
// inf, overflow), wrong argument counts, undefined names, unbalanced `xf` (per file) or `o` end
// without begin, include cycles, missing includes, nesting deeper than max_depth, illegal radii,
// budgets. Warnings go to SceneDescription::warnings ("file:line: ...") and spdlog; after
// 500 of them the rest are only counted, in one final summary warning.

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

#include "common/scene/mgf_options.h"
#include "common/scene/scene.h"

namespace pf {

// Loads an MGF file and everything it includes. Throws InputError on malformed input.
SceneDescription LoadMgf(const std::filesystem::path& file, const MgfOptions& options = {});

// Same, from memory; `virtual_name` is used in messages and as base dir for `i` includes
// (the current directory if it has none).
SceneDescription LoadMgfFromString(std::string_view text, const std::string& virtual_name,
                                   const MgfOptions& options = {});

// The colour conversions above (mgf::CieToRgb, mgf::SpectrumToXy, mgf::kLuminousEfficacy) are
// declared in mgf_color.h, for tests and for tools that print material tables.

}  // namespace pf
