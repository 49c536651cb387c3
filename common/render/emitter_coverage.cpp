#include "common/render/emitter_coverage.h"

#include <tbb/parallel_for.h>

namespace pf {

std::vector<float> EmitterCoverage(const EmbreeScene& scene, const Camera& camera, int grid) {
  const int width = camera.width(), height = camera.height();
  std::vector<float> coverage(size_t(width) * size_t(height), 0.0f);
  const SceneDescription& desc = scene.description();
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      int hits = 0;
      for (int j = 0; j < grid; ++j)
        for (int i = 0; i < grid; ++i) {
          const Ray ray =
              camera.GenerateRay(x, y, (float(i) + 0.5f) / float(grid), (float(j) + 0.5f) / float(grid));
          const std::optional<SurfaceHit> hit = scene.Intersect(ray);
          hits += hit && hit->front_face && desc.materials[hit->material].IsEmissive();
        }
      coverage[size_t(y) * size_t(width) + size_t(x)] = float(hits) / float(grid * grid);
    }
  });
  return coverage;
}

}  // namespace pf
