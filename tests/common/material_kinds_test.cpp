// common/scene/material_kinds.h: every kind a manifest names parses and makes a material of
// that kind; an unknown kind lists the known ones; a kind refuses a parameter it needs and
// lacks, naming it.

#include "common/scene/material_kinds.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "common/core/error.h"
#include "common/scene/manifest.h"
#include "tests/util/input_error.h"

namespace pf {
namespace {

using ::testing::HasSubstr;

MaterialOverride Parse(const std::string& material_json) {
  const SceneManifest m =
      ParseManifest(R"({"geometry": "x.obj", "materials": {"m": )" + material_json + "}}", "scene.json");
  return m.materials.at("m");
}

std::string ParseError(const std::string& material_json) {
  return testing::InputErrorOf([&] { Parse(material_json); });
}

// A material with every lobe.
Material Everything() {
  Material m;
  m.diffuse_reflectance = Rgb(0.2f);
  m.specular_reflectance = Rgb(0.2f);
  m.specular_roughness = 0.1f;
  m.diffuse_transmittance = Rgb(0.1f);
  m.specular_transmittance = Rgb(0.1f);
  m.ior = 1.3f;
  return m;
}

TEST(MaterialKinds, EveryKindParsesAndMakesItsMaterial) {
  ASSERT_EQ(MaterialKinds().entries().size(), 6u);
  for (const MaterialKind& k : MaterialKinds().entries()) {
    const bool rough = k.name == "glossy" || k.name == "metal" || k.name == "rough-glass";
    const std::string extra = rough ? R"(, "roughness": 0.2)" : "";
    EXPECT_EQ(Parse(R"({"kind": ")" + std::string(k.name) + "\"" + extra + "}").kind, k.kind) << k.name;
    EXPECT_EQ(MaterialKinds().GetKind(k.kind), &k);
    EXPECT_EQ(MaterialKinds().Get(k.name), &k);
  }
  EXPECT_EQ(MaterialKinds().GetKind(MaterialOverride::Kind::kUnchanged), nullptr);
  Material m = Everything();
  MaterialKinds().Get("diffuse")->apply(&m);
  EXPECT_TRUE(m.specular_reflectance.IsBlack() && m.specular_transmittance.IsBlack() && m.ior == 1.0f);
  EXPECT_EQ(m.diffuse_reflectance, Rgb(0.2f));
  m = Everything();
  MaterialKinds().Get("glossy")->apply(&m);
  EXPECT_EQ(m.specular_roughness, 0.1f);
  EXPECT_TRUE(m.diffuse_transmittance.IsBlack() && m.specular_transmittance.IsBlack());
  m = Material{};
  MaterialKinds().Get("mirror")->apply(&m);
  EXPECT_EQ(m.specular_reflectance, Rgb(1.0f));
  EXPECT_EQ(m.specular_roughness, 0.0f);
  m = Material{};
  MaterialKinds().Get("glass")->apply(&m);
  EXPECT_EQ(m.specular_transmittance, Rgb(1.0f));
  EXPECT_EQ(m.ior, 1.5f);
  EXPECT_EQ(m.microfacet, Material::Microfacet::kNone);
  // The GGX kinds: a white metal (ρs = F0), a rough glass; the Ward kinds undo them.
  m = Everything();
  MaterialKinds().Get("metal")->apply(&m);
  EXPECT_EQ(m.microfacet, Material::Microfacet::kConductor);
  EXPECT_EQ(m.specular_reflectance, Rgb(0.2f));
  EXPECT_TRUE(m.diffuse_reflectance.IsBlack() && m.specular_transmittance.IsBlack() &&
              m.diffuse_transmittance.IsBlack());
  m = Material{};
  MaterialKinds().Get("metal")->apply(&m);
  EXPECT_EQ(m.specular_reflectance, Rgb(1.0f));
  m = Everything();
  MaterialKinds().Get("rough-glass")->apply(&m);
  EXPECT_EQ(m.microfacet, Material::Microfacet::kDielectric);
  EXPECT_EQ(m.specular_transmittance, Rgb(0.1f));
  EXPECT_EQ(m.ior, 1.3f);
  EXPECT_TRUE(m.diffuse_reflectance.IsBlack() && m.specular_reflectance.IsBlack());
  m.microfacet_roughness = 0.5f;
  MaterialKinds().Get("glass")->apply(&m);
  EXPECT_EQ(m.microfacet, Material::Microfacet::kNone);
  EXPECT_EQ(m.microfacet_roughness, 0.0f);
}

TEST(MaterialKinds, UnknownKindListsTheKnownOnes) {
  EXPECT_THAT(
      ParseError(R"({"kind": "velvet"})"),
      HasSubstr("key 'materials.m.kind': expected one of \"diffuse\", \"glossy\", \"mirror\", \"glass\", "
                "\"metal\", \"rough-glass\""));
}

TEST(MaterialKinds, AKindRefusesAParameterItNeedsNamingIt) {
  EXPECT_THAT(ParseError(R"({"kind": "glossy"})"),
              HasSubstr("key 'materials.m.roughness': missing (kind \"glossy\" needs a Ward roughness > 0)"));
  EXPECT_THAT(ParseError(R"({"kind": "glossy", "roughness": 0})"),
              HasSubstr("key 'materials.m.roughness': kind \"glossy\" needs a Ward roughness > 0"));
  EXPECT_EQ(ParseError(R"({"kind": "mirror", "roughness": 0})"), "(no error)");
  EXPECT_THAT(
      ParseError(R"({"kind": "metal"})"),
      HasSubstr("key 'materials.m.roughness': missing (kind \"metal\" needs a GGX roughness in [0, 1])"));
  EXPECT_THAT(ParseError(R"({"kind": "rough-glass", "roughness": 1.5})"),
              HasSubstr("key 'materials.m.roughness': kind \"rough-glass\" needs a GGX roughness in [0, 1]"));
  EXPECT_EQ(ParseError(R"({"kind": "metal", "roughness": 0})"), "(no error)");
  EXPECT_EQ(ParseError(R"({"kind": "rough-glass", "roughness": 1})"), "(no error)");
}

}  // namespace
}  // namespace pf
