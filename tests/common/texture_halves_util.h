#pragma once
// A plane whose texture gives its two halves two materials, against the same plane with two
// untextured materials (tests/common/*_texture_test.cpp): away from the seam the two renders must
// be the very same pixels, and the halves must differ (a texture read wrongly, or not at all,
// would make both halves one material).

#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "common/scene/scene.h"
#include "tests/common/gltf_test_util.h"
#include "tests/common/scene_render_util.h"

namespace pf::texture_halves {

// The lobes of two materials (what a per-hit re-mapping gives against what the mapping gives).
inline void ExpectSameMaterial(const Material& got, const Material& want) {
  EXPECT_EQ(got.diffuse_reflectance, want.diffuse_reflectance);
  EXPECT_EQ(got.specular_reflectance, want.specular_reflectance);
  EXPECT_EQ(got.specular_transmittance, want.specular_transmittance);
  EXPECT_EQ(got.microfacet, want.microfacet);
  EXPECT_EQ(got.microfacet_roughness, want.microfacet_roughness);
  EXPECT_EQ(got.microfacet_f90, want.microfacet_f90);
}

// An 8-bit RGB PNG of `w` x `h` from row-major codes.
inline void WritePng(const std::filesystem::path& path, int w, int h, const std::vector<unsigned char>& rgb) {
  ASSERT_EQ(rgb.size(), size_t(w) * size_t(h) * 3);
  ASSERT_NE(stbi_write_png(path.string().c_str(), w, h, 3, rgb.data(), w * 3), 0);
}

// 8 x 8 codes: `left` in the columns x < 4, `right` in the others.
inline std::vector<unsigned char> Halves(std::vector<unsigned char> left, std::vector<unsigned char> right) {
  std::vector<unsigned char> rgb;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      rgb.insert(rgb.end(), (x < 4 ? left : right).begin(), (x < 4 ? left : right).end());
  return rgb;
}

// The plane: 2 x 2 m at z = 0 facing +z, in two halves x < 0 and x > 0 (two triangles each:
// vertices 0..5 are (−1,−1) (0,−1) (1,−1) (−1,1) (0,1) (1,1)); TEXCOORD_0 spans the image
// (glTF's v downwards). Accessors: 0 POSITION, 1 NORMAL, 2 TEXCOORD_0, 3 left indices, 4 right
// indices, 5 all indices.
inline gltf_test::GltfBuilder Plane() {
  gltf_test::GltfBuilder b;
  b.AddVec3({-1, -1, 0, 0, -1, 0, 1, -1, 0, -1, 1, 0, 0, 1, 0, 1, 1, 0});
  b.AddVec3({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1});
  b.AddVec2({0, 1, 0.5f, 1, 1, 1, 0, 0, 0.5f, 0, 1, 0});
  b.AddIndices16({0, 1, 4, 0, 4, 3});
  b.AddIndices16({1, 2, 5, 1, 5, 4});
  b.AddIndices16({0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4});
  return b;
}

// Scene `a` (the textured plane) and scene `b` (two untextured materials) rendered with
// `integrator` at 32 x 32, 16 spp: pixels at least two columns from the seam (the bilinear filter
// blends the halves within half a texel, 1/8 m = 2 pixels, of it) bit-identical, and the halves'
// sums differing in some channel by more than `min_difference` of the larger.
inline void ExpectHalvesMatch(const std::filesystem::path& a_file, const std::filesystem::path& b_file,
                              const char* integrator, float min_difference = 0.05f) {
  const Image a = render_test::RenderScene(a_file, integrator, 16, 20000);
  const Image b = render_test::RenderScene(b_file, integrator, 16, 20000);
  int compared = 0, differing = 0;
  Rgb left(0.0f), right(0.0f);
  for (int y = 2; y < 30; ++y)
    for (int x = 2; x < 30; ++x) {
      if (x >= 14 && x <= 17) continue;
      ++compared;
      if (!(a.at(x, y) == b.at(x, y))) ++differing;
      (x < 16 ? left : right) += a.at(x, y);
    }
  std::cout << integrator << ": " << differing << " of " << compared << " pixels differ; left sums " << left.r
            << " " << left.g << " " << left.b << ", right " << right.r << " " << right.g << " " << right.b
            << "\n";
  EXPECT_EQ(differing, 0) << integrator;
  float difference = 0.0f;
  for (int c = 0; c < 3; ++c)
    difference =
        std::max(difference, std::abs(left[c] - right[c]) - min_difference * std::max(left[c], right[c]));
  EXPECT_GT(difference, 0.0f) << integrator << ": the halves look alike";
}

}  // namespace pf::texture_halves
