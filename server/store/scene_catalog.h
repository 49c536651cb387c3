#pragma once
// What the coordinator knows about a stored scene, and the lookup the job validation
// (server/jobs/job_spec.h) needs: store/ defines it, SceneStore implements it, so the store does
// not depend on jobs/ (layers point down: store < jobs < scheduling, docs/design.md).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace pf::server {

// What the coordinator knows about a stored scene.
struct SceneInfo {
  std::string hash;
  std::string entry;
  uint64_t triangles = 0;
  uint32_t lights = 0;
  double max_emission = -1;  // the brightest emitter's largest channel (Le); -1 = unknown (old database)
  int caustic_paths = -1;    // 1: specular or glossy surfaces (a caustic map is built); -1 = unknown
  uint64_t bytes = 0;
  uint64_t files = 0;
  CameraSpec camera;  // the manifest's first camera, else DefaultCamera(scene)
  std::vector<std::string> warnings;
};

class SceneCatalog {
 public:
  virtual ~SceneCatalog() = default;
  virtual std::optional<SceneInfo> FindScene(const std::string& hash) const = 0;
};

}  // namespace pf::server
