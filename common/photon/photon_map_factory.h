#pragma once
// The photon-map structures by name (docs/settings.md, `structure`): a registry of builders,
// each of which checks its own options (PhotonMapOptions) before it builds an empty map. The
// names are the `structure` setting's choices (common/render/render_settings_table.cpp); a test
// checks that both list the same (tests/common/photon_map_factory_test.cpp). A new structure is
// an entry here and a choice there.

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/named_registry.h"
#include "common/photon/photon_map.h"

namespace pf {

struct PhotonMapStructure {
  std::string_view name = {};  // as the `structure` setting spells it: "kdtree"
  PhotonMapKind kind = PhotonMapKind::kKdTree;
  // Whether its maps have a byte form (photon_maps_bytes.h) and can therefore travel: distributed
  // map tracing (docs/farm.md, "Photon maps traced once") needs it.
  bool serializable = false;
  // The settings (rows of the settings table, render_settings_table.h) that only this structure
  // reads: the table asks Reads whether such a setting applies (UnusedSettings, the map key).
  std::vector<std::string_view> settings = {};
  // An empty map of this structure. InputError naming the option when `options` are invalid.
  std::function<std::unique_ptr<PhotonMap>(const PhotonMapOptions& options)> build = nullptr;

  bool Reads(std::string_view setting) const {
    for (std::string_view s : settings)
      if (s == setting) return true;
    return false;
  }
};

// Every structure, in the order of the `structure` setting's choices.
const NamedRegistry<PhotonMapStructure>& PhotonMapStructures();

// An empty map of `kind` (PhotonMapStructures().FindKind(kind).build).
std::unique_ptr<PhotonMap> MakePhotonMap(PhotonMapKind kind, const PhotonMapOptions& options = {});

}  // namespace pf
