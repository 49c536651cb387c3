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
// Colour: the image is linear RGB as image/image_file.h decodes it (PNG/JPEG as sRGB, EXR/HDR
// linear): right for colour slots (baseColor, map_Kd); data slots (metallic-roughness, normals)
// are not read (the loaders warn).

#include <array>
#include <cstdint>
#include <memory>
#include <string>

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

  // The bilinearly filtered colour at `uv`. A non-finite coordinate reads texel (0, 0).
  Rgb Lookup(const TextureCoordinates& uv) const;
};

// The texel index of an integer index `i` on an axis of `size` texels under `wrap`.
int WrapTexelIndex(int64_t i, int size, TextureWrap wrap);

}  // namespace pf
