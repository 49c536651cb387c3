#pragma once
// Image textures: a decoded image and how it is looked up (docs/renderer.md, "Textures").
//
// Texture coordinates follow glTF's convention (specification §3.8.4): (0, 0) is the top-left
// corner of the image, u to the right, v downwards; one unit spans the image. Loaders convert
// (OBJ's `vt` has v upwards: v_glTF = 1 − v_OBJ).
//
// Filtering: bilinear between the four texels around the point (texel centres at
// (i + ½)/width), each index wrapped by the texture's mode. No mip-mapping: a texture minified on
// screen is anti-aliased by the pixel's own samples (every integrator takes several jittered
// camera samples per pixel), which converge to the box-filtered texture; a mip pyramid would add
// a ray differential to every path vertex for a bias the farm's sample counts remove anyway.
//
// Values: the image is linear RGB as image/image_file.h decodes it for the slot the texture
// serves: 8/16-bit codes by the sRGB curve for colour slots (baseColor, map_Kd), as code / max for
// data slots (glTF metallicRoughness; ImageCodes::kData). The alpha channel, when a slot reads
// it (a mask: glTF baseColor under alphaMode MASK, OBJ map_d), is linear and filtered like the
// colour.

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/core/math.h"
#include "common/image/image.h"

namespace pf {

// glTF sampler wrap modes (specification §5.26: 10497 REPEAT, 33071 CLAMP_TO_EDGE,
// 33648 MIRRORED_REPEAT); OBJ's `-clamp on` is kClampToEdge.
enum class TextureWrap : uint8_t { kRepeat, kClampToEdge, kMirroredRepeat };

using TextureCoordinates = std::array<float, 2>;  // (u, v), the convention above

struct Texture {
  std::string source;                  // as the scene names it ("wood.png", "images[2]"): messages
  std::shared_ptr<const Image> image;  // linear RGB, never empty; shared by textures of one image
  TextureWrap wrap_u = TextureWrap::kRepeat;
  TextureWrap wrap_v = TextureWrap::kRepeat;
  // Per texel (row-major, the image's size) or null (alpha 1 everywhere): the coverage a mask
  // reads (scene.h, Material::alpha_cutoff).
  std::shared_ptr<const std::vector<float>> alpha;

  // The bilinearly filtered colour at `uv`. A non-finite coordinate reads texel (0, 0).
  Rgb Lookup(const TextureCoordinates& uv) const;
  // The alpha at `uv`, filtered the same way (1 without an alpha channel).
  float LookupAlpha(const TextureCoordinates& uv) const;
};

// The texel index of an integer index `i` on an axis of `size` texels under `wrap`.
int WrapTexelIndex(int64_t i, int size, TextureWrap wrap);

}  // namespace pf
