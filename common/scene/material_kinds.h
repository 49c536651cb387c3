#pragma once
// The material kinds by name (a manifest's materials.<name>.kind, docs/scene-manifest.md): a
// registry of what each kind makes of a loaded material and which of its parameters it needs,
// in the manner of Mitsuba's BSDF plugins by name. There is one BSDF (materials/bsdf.h: diffuse
// + specular/Ward reflection and transmission, or GGX microfacet lobes, from a Material); a kind
// is a recipe for its parameters. The registry lives in scene/ because the manifest and the scene loader,
// which build through it, are below materials/ (common/CMakeLists.txt, the layers). A new kind is an entry
// here.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/named_registry.h"
#include "common/scene/manifest.h"
#include "common/scene/scene.h"

namespace pf {

struct MaterialKind {
  std::string_view name = {};  // as the manifest writes it: "glossy"
  MaterialOverride::Kind kind = MaterialOverride::Kind::kDiffuse;
  // Checks the parameters of a manifest entry of this kind: calls `fail(parameter, reason)`
  // (which throws) for one it needs and lacks or cannot use.
  std::function<void(const MaterialOverride& o, const std::function<void(const std::string& parameter,
                                                                         const std::string& reason)>& fail)>
      check = nullptr;
  // Makes `m` of this kind: clears the lobes the kind has not, fills the ones it needs; the
  // entry's explicit parameters are applied after (scene_loader.cpp, ApplyMaterialOverrides).
  std::function<void(Material* m)> apply = nullptr;
};

// Every kind, in the order the manifest's documentation lists them.
// GetKind(kUnchanged) is nullptr: no kind given, the loaded material stays.
const NamedRegistry<MaterialKind>& MaterialKinds();
// "\"diffuse\", \"glossy\", \"mirror\", \"glass\", \"metal\", \"rough-glass\"" (for "expected one of ...").
std::string QuotedMaterialKindNames();

}  // namespace pf
