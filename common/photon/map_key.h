#pragma once
// The identity of one photon map (docs/farm.md "Photon maps traced once"): the scene it is traced
// in, the settings that decide its photons and its seed. Photon i of a map depends on the scene,
// those settings, the seed and i alone (photon_tracer.h), so two maps with one key hold the same
// photons bit for bit: the key names the map wherever it is kept — the in-process cache
// (PhotonMapCache), the coordinator's store of maps traced in pieces and a worker's disk cache.
//
// The fingerprint is the caller's: any text that changes whenever a setting that changes the map
// does (JobRenderSettings::MapFingerprint of resolved settings for the in-process cache; the
// coordinator's key uses the job's whole settings, which with the scene decide every `auto`).

#include <cstdint>
#include <string>
#include <string_view>

namespace pf {

struct MapKey {
  std::string scene;        // the scene's content hash
  std::string fingerprint;  // the settings that decide the map's photons (see above)
  uint64_t seed = 0;        // the map seed

  // The in-process cache's key: "scene|fingerprint|seed", readable in logs.
  std::string Text() const;
  // The content address of the map's file: hex SHA-256 of a versioned text of the key and of
  // `build`, the program's version (a map traced by another build before an upgrade may hold
  // other photons and is never reused: docs/farm.md, Upgrades).
  std::string Address(std::string_view build) const;
  // Whether `text` has the form of an Address (64 lowercase hex digits): a file name, never a path.
  static bool IsAddress(std::string_view text);
};

}  // namespace pf
