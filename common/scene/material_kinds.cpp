#include "common/scene/material_kinds.h"

namespace pf {
namespace {

using Fail = std::function<void(const std::string&, const std::string&)>;

void NoCheck(const MaterialOverride&, const Fail&) {}

// No transmission (diffuse, glossy and mirror are opaque).
void ClearTransmission(Material* m) {
  m->diffuse_transmittance = Rgb();
  m->specular_transmittance = Rgb();
  m->transmission_roughness = 0.0f;
  m->ior = 1.0f;
}

// Ward's lobes again (the kinds before "metal" are Ward's model, scene.h).
void ClearMicrofacet(Material* m) {
  m->microfacet = Material::Microfacet::kNone;
  m->microfacet_roughness = 0.0f;
}

void MakeDiffuse(Material* m) {
  ClearMicrofacet(m);
  m->specular_reflectance = Rgb();
  m->specular_roughness = 0.0f;
  ClearTransmission(m);
}

void MakeGlossy(Material* m) {
  ClearMicrofacet(m);
  ClearTransmission(m);
}

// A Ward lobe needs its roughness (α > 0; α = 0 is the mirror).
void CheckGlossy(const MaterialOverride& o, const Fail& fail) {
  if (!o.roughness) return fail("roughness", "missing (kind \"glossy\" needs a Ward roughness > 0)");
  if (!(*o.roughness > 0.0f)) fail("roughness", "kind \"glossy\" needs a Ward roughness > 0");
}

void MakeMirror(Material* m) {
  ClearMicrofacet(m);
  if (m->specular_reflectance.IsBlack()) m->specular_reflectance = Rgb(1.0f);
  m->specular_roughness = 0.0f;
  m->diffuse_reflectance = Rgb();
  ClearTransmission(m);
}

void MakeGlass(Material* m) {
  ClearMicrofacet(m);
  if (m->specular_transmittance.IsBlack()) m->specular_transmittance = Rgb(1.0f);
  if (!(m->ior > 1.0f)) m->ior = 1.5f;
  m->diffuse_reflectance = Rgb();
  m->specular_reflectance = Rgb();
  m->specular_roughness = 0.0f;
  m->diffuse_transmittance = Rgb();
  m->transmission_roughness = 0.0f;
}

// The GGX kinds need the glTF roughness r in [0, 1] (α = r²; r < 0.0316 renders smooth).
void CheckMicrofacetRoughness(const MaterialOverride& o, const std::string& kind, const Fail& fail) {
  if (!o.roughness)
    return fail("roughness", "missing (kind \"" + kind + "\" needs a GGX roughness in [0, 1])");
  if (!(*o.roughness <= 1.0f)) fail("roughness", "kind \"" + kind + "\" needs a GGX roughness in [0, 1]");
}

void CheckMetal(const MaterialOverride& o, const Fail& fail) {
  CheckMicrofacetRoughness(o, "metal", fail);
}

// A GGX conductor: ρs is F0 of Schlick's Fresnel (1 if it was black: a white metal).
void MakeMetal(Material* m) {
  MakeMirror(m);
  m->microfacet = Material::Microfacet::kConductor;
}

void CheckRoughGlass(const MaterialOverride& o, const Fail& fail) {
  CheckMicrofacetRoughness(o, "rough-glass", fail);
}

// A GGX dielectric (Walter et al. 2007): τs and ior as for "glass".
void MakeRoughGlass(Material* m) {
  MakeGlass(m);
  m->microfacet = Material::Microfacet::kDielectric;
}

}  // namespace

const NamedRegistry<MaterialKind>& MaterialKinds() {
  using K = MaterialOverride::Kind;
  static const NamedRegistry<MaterialKind> registry(
      "material kind", {{"diffuse", K::kDiffuse, NoCheck, MakeDiffuse},
                        {"glossy", K::kGlossy, CheckGlossy, MakeGlossy},
                        {"mirror", K::kMirror, NoCheck, MakeMirror},
                        {"glass", K::kGlass, NoCheck, MakeGlass},
                        {"metal", K::kMetal, CheckMetal, MakeMetal},
                        {"rough-glass", K::kRoughGlass, CheckRoughGlass, MakeRoughGlass}});
  return registry;
}

std::string QuotedMaterialKindNames() {
  std::string out;
  for (const MaterialKind& k : MaterialKinds().entries())
    out += (out.empty() ? "\"" : ", \"") + std::string(k.name) + "\"";
  return out;
}

}  // namespace pf
