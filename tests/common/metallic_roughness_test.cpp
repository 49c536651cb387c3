// common/scene/metallic_roughness.h: the glTF metallic-roughness mapping's parameters, and a
// white furnace of the mixed material (Lambertian + GGX conductor lobe, F90 capped) through
// Bsdf: at most 1 at every angle.

#include "common/scene/metallic_roughness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/materials/bsdf.h"
#include "tests/common/bsdf_test_support.h"

namespace pf {
namespace {

TEST(MetallicRoughness, MapsTheGltfParameters) {
  const Rgb base(0.8f, 0.4f, 0.2f);
  const Material metal = MetallicRoughnessMaterial({.base_color = base, .metallic = 1.0f, .roughness = 0.3f});
  EXPECT_EQ(metal.microfacet, Material::Microfacet::kConductor);
  EXPECT_EQ(metal.specular_reflectance, base);
  EXPECT_TRUE(metal.diffuse_reflectance.IsBlack());
  EXPECT_EQ(metal.microfacet_roughness, 0.3f);
  EXPECT_EQ(metal.microfacet_f90, 1.0f);
  const Material plastic =
      MetallicRoughnessMaterial({.base_color = base, .metallic = 0.0f, .roughness = 0.5f});
  EXPECT_EQ(plastic.specular_reflectance, Rgb(0.04f));
  EXPECT_NEAR(plastic.diffuse_reflectance.r, 0.8f * 0.96f, 1e-6f);
  EXPECT_EQ(plastic.microfacet_f90, 0.04f);
  const Material half = MetallicRoughnessMaterial({.base_color = base, .metallic = 0.5f, .roughness = 0.5f});
  EXPECT_NEAR(half.specular_reflectance.g, 0.02f + 0.2f, 1e-6f);
  EXPECT_NEAR(half.diffuse_reflectance.g, 0.4f * 0.5f * 0.96f, 1e-6f);
  // KHR_materials_transmission: a rough dielectric tinted by the base colour.
  const Material glass = MetallicRoughnessMaterial(
      {.base_color = base, .metallic = 0.0f, .roughness = 0.2f, .transmission = 1.0f});
  EXPECT_EQ(glass.microfacet, Material::Microfacet::kDielectric);
  EXPECT_EQ(glass.specular_transmittance, base);
  EXPECT_EQ(glass.ior, 1.5f);
  // Out-of-range and NaN inputs are clamped to the range or the glTF default.
  const Material odd = MetallicRoughnessMaterial(
      {.base_color = Rgb(2.0f, -1.0f, std::nanf("")), .metallic = std::nanf(""), .roughness = 7.0f});
  EXPECT_EQ(odd.specular_reflectance, Rgb(1.0f, 0.0f, 1.0f));
  EXPECT_EQ(odd.microfacet_roughness, 1.0f);
}

TEST(MetallicRoughness, WhiteFurnaceOfTheMix) {
  double worst = 0;
  for (float metallic : {0.0f, 0.5f, 1.0f}) {
    for (float roughness : {0.2f, 0.5f, 1.0f}) {
      const Material m =
          MetallicRoughnessMaterial({.base_color = Rgb(1.0f), .metallic = metallic, .roughness = roughness});
      const Bsdf bsdf(m, Vec3(0, 0, 1), Vec3(0, 0, 1));
      for (float c : {1.0f, 0.5f, 0.2f, 0.02f}) {
        const bsdf_test::Albedo a = bsdf_test::EstimateAlbedo(bsdf, bsdf_test::FromCos(c), 100'000, 3);
        std::printf("[furnace] metallic-roughness m=%.1f r=%.1f cos %.2f albedo %.4f ± %.4f\n", metallic,
                    roughness, c, a.mean[0], a.sigma[0]);
        worst = std::max(worst, a.mean[0]);
        EXPECT_LE(a.mean[0], 1.0 + 3 * a.sigma[0]) << metallic << " " << roughness << " cos " << c;
      }
    }
  }
  std::printf("[furnace] metallic-roughness worst albedo %.4f\n", worst);
}

}  // namespace
}  // namespace pf
