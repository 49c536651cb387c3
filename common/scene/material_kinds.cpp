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

void MakeDiffuse(Material* m) {
  m->specular_reflectance = Rgb();
  m->specular_roughness = 0.0f;
  ClearTransmission(m);
}

void MakeGlossy(Material* m) {
  ClearTransmission(m);
}

// A Ward lobe needs its roughness (α > 0; α = 0 is the mirror).
void CheckGlossy(const MaterialOverride& o, const Fail& fail) {
  if (!o.roughness) return fail("roughness", "missing (kind \"glossy\" needs a Ward roughness > 0)");
  if (!(*o.roughness > 0.0f)) fail("roughness", "kind \"glossy\" needs a Ward roughness > 0");
}

void MakeMirror(Material* m) {
  if (m->specular_reflectance.IsBlack()) m->specular_reflectance = Rgb(1.0f);
  m->specular_roughness = 0.0f;
  m->diffuse_reflectance = Rgb();
  ClearTransmission(m);
}

void MakeGlass(Material* m) {
  if (m->specular_transmittance.IsBlack()) m->specular_transmittance = Rgb(1.0f);
  if (!(m->ior > 1.0f)) m->ior = 1.5f;
  m->diffuse_reflectance = Rgb();
  m->specular_reflectance = Rgb();
  m->specular_roughness = 0.0f;
  m->diffuse_transmittance = Rgb();
  m->transmission_roughness = 0.0f;
}

}  // namespace

const NamedRegistry<MaterialKind>& MaterialKinds() {
  using K = MaterialOverride::Kind;
  static const NamedRegistry<MaterialKind> registry("material kind",
                                                    {{"diffuse", K::kDiffuse, NoCheck, MakeDiffuse},
                                                     {"glossy", K::kGlossy, CheckGlossy, MakeGlossy},
                                                     {"mirror", K::kMirror, NoCheck, MakeMirror},
                                                     {"glass", K::kGlass, NoCheck, MakeGlass}});
  return registry;
}

std::string QuotedMaterialKindNames() {
  std::string out;
  for (const MaterialKind& k : MaterialKinds().entries())
    out += (out.empty() ? "\"" : ", \"") + std::string(k.name) + "\"";
  return out;
}

}  // namespace pf
