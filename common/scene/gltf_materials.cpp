// glTF materials → Material (gltf_materials.h).
#include "common/scene/gltf_materials.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>

#include "common/core/error.h"
#include "common/scene/metallic_roughness.h"

namespace pf {

namespace {

float Unit(double v) {
  return float(std::clamp(v, 0.0, 1.0));
}

// A number of an extension's object, or `fallback` if the extension or the key is absent.
double ExtensionNumber(const tinygltf::Material& m, const char* extension, const char* key, double fallback) {
  const auto it = m.extensions.find(extension);
  if (it == m.extensions.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
  const tinygltf::Value& v = it->second.Get(key);
  return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
}

// The texture slots a material uses that are not applied, in the spec's order (baseColorTexture,
// metallicRoughnessTexture, emissiveTexture and transmissionTexture are: gltf_loader.cpp,
// gltf_textures.h).
std::vector<std::string> UnappliedTextureSlots(const tinygltf::Material& m) {
  std::vector<std::string> slots;
  if (m.normalTexture.index >= 0) slots.push_back("normalTexture");
  if (m.occlusionTexture.index >= 0) slots.push_back("occlusionTexture");
  return slots;
}

}  // namespace

Material DefaultGltfMaterial() {
  Material m;
  m.name = "(glTF default)";
  m.diffuse_reflectance = Rgb(1.0f);
  return m;
}

Material MapGltfMaterial(const tinygltf::Material& g, size_t index, const std::string& file,
                         std::vector<std::string>* warnings) {
  const std::string where =
      "materials[" + std::to_string(index) + "]" + (g.name.empty() ? "" : " '" + g.name + "'");
  const std::vector<double>& bc = g.pbrMetallicRoughness.baseColorFactor;
  const Rgb base = bc.size() >= 3 ? Rgb(Unit(bc[0]), Unit(bc[1]), Unit(bc[2])) : Rgb(1.0f);
  const float metallic = Unit(g.pbrMetallicRoughness.metallicFactor);
  const float roughness = Unit(g.pbrMetallicRoughness.roughnessFactor);
  const float transmission =
      Unit(ExtensionNumber(g, "KHR_materials_transmission", "transmissionFactor", 0.0));
  const double ior = ExtensionNumber(g, "KHR_materials_ior", "ior", 1.5);
  const double strength = ExtensionNumber(g, "KHR_materials_emissive_strength", "emissiveStrength", 1.0);

  if (transmission > 0.0f && !(ior >= 1.0 && ior <= 10.0))
    throw InputError(
        SourceLocation{file, 0},
        where + ": KHR_materials_ior.ior must be a number in [1, 10], got " + std::to_string(ior));
  // glTF's metallic-roughness model on pf's GGX lobes (metallic_roughness.h).
  const MetallicRoughness params{.base_color = base,
                                 .metallic = metallic,
                                 .roughness = roughness,
                                 .transmission = transmission,
                                 .ior = float(ior)};
  Material m = MetallicRoughnessMaterial(params);
  m.metallic_roughness = params;
  m.name = g.name.empty() ? "materials[" + std::to_string(index) + "]" : g.name;
  if (g.emissiveFactor.size() >= 3) {
    if (!(strength >= 0.0))
      throw InputError(SourceLocation{file, 0},
                       where + ": KHR_materials_emissive_strength.emissiveStrength must be >= 0");
    for (int c = 0; c < 3; ++c) {
      const double le = std::clamp(g.emissiveFactor[size_t(c)], 0.0, 1.0) * strength;
      if (!(le <= double(kMaxLightIntensity)))
        throw InputError(SourceLocation{file, 0}, where + ": emissiveFactor x emissiveStrength exceeds " +
                                                      std::to_string(kMaxLightIntensity));
      (c == 0 ? m.emission.r : c == 1 ? m.emission.g : m.emission.b) = float(le);
    }
  }
  m.one_sided = !g.doubleSided;

  const std::vector<std::string> slots = UnappliedTextureSlots(g);
  if (!slots.empty()) {
    std::string list;
    for (const std::string& s : slots) list += (list.empty() ? "" : ", ") + s;
    warnings->push_back(file + ": " + where + ": textures not applied: " + list +
                        " (their factors alone are used; only baseColorTexture, "
                        "metallicRoughnessTexture, emissiveTexture and transmissionTexture are applied)");
  }
  // Alpha (specification §3.9.4; docs/gltf.md, "Alpha"): MASK cuts the surface out where
  // baseColorFactor.a × the base colour texture's alpha < alphaCutoff (the loader adds the
  // texture); BLEND is rendered as MASK at 0.5 (a path tracer's rays see a surface or not). An
  // emitter stays opaque: its light is sampled over its whole area (light/).
  if (g.alphaMode == "MASK" || g.alphaMode == "BLEND") {
    const bool blend = g.alphaMode == "BLEND";
    if (blend)
      warnings->push_back(file + ": " + where +
                          ": alphaMode BLEND is rendered as MASK with alphaCutoff 0.5 (no partial coverage)");
    if (m.IsEmissive()) {
      warnings->push_back(file + ": " + where + ": alphaMode " + g.alphaMode +
                          " is not applied to an emitting material (the surface is opaque)");
    } else {
      m.alpha_cutoff = blend ? 0.5f : float(std::max(g.alphaCutoff, 0.0));
      m.alpha_factor = bc.size() >= 4 ? Unit(bc[3]) : 1.0f;
    }
  } else if (g.alphaMode != "OPAQUE" && !g.alphaMode.empty()) {
    warnings->push_back(file + ": " + where + ": alphaMode " + g.alphaMode +
                        " is not a glTF alpha mode (the surface is opaque)");
  }
  return m;
}

}  // namespace pf
