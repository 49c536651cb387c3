#pragma once
// Budgets for what loading one scene may produce (docs/security.md, "Scene budgets").
//
// Scene files are untrusted input (bundles uploaded to the coordinator), and small files can
// expand enormously: an MGF array (`xf -a N`, `i file -a N`, mgfdoc.tr §2.2.3) runs its block N
// times, nested arrays multiply, and one `sph` line is 576 triangles. So the loaders compute
// what a file expands to *before* doing the work — the MGF loader from its entities and the
// nesting multipliers of its arrays and includes, the OBJ loader from its statements — and
// refuse a file that exceeds a budget with an InputError naming the file, the line where the
// expansion crossed it, and the budget. The counts are exact for entities and instances and
// upper bounds for triangles and vertices (degenerate faces are dropped later).

#include <cstdint>
#include <limits>
#include <string>

namespace pf {

// What loading a file expands to.
struct SceneExpansion {
  uint64_t entities = 0;   // MGF entities executed (array repeats and includes counted); OBJ statements
  uint64_t instances = 0;  // MGF array instances (`-a`), nested arrays multiplied
  uint64_t triangles = 0;  // at most this many triangles
  uint64_t vertices = 0;   // at most this many vertices (OBJ: v, vn and vt statements)

  // Saturating arithmetic: a count that overflows stays at the largest value (beyond any budget).
  static uint64_t Add(uint64_t a, uint64_t b) {
    return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max() : a + b;
  }
  static uint64_t Multiply(uint64_t a, uint64_t b) {
    return b != 0 && a > std::numeric_limits<uint64_t>::max() / b ? std::numeric_limits<uint64_t>::max()
                                                                  : a * b;
  }
  // This plus `times` executions of `other`.
  void AddTimes(const SceneExpansion& other, uint64_t times) {
    entities = Add(entities, Multiply(other.entities, times));
    instances = Add(instances, Multiply(other.instances, times));
    triangles = Add(triangles, Multiply(other.triangles, times));
    vertices = Add(vertices, Multiply(other.vertices, times));
  }
};

struct SceneBudget {
  // Defaults: generous for every shipped scene and every scene of /work/shared/scenes that loads
  // (the largest, soda.mgf: 196k triangles; docs/security.md has the table), and they bound one
  // load to about 2 GB (measured: docs/security.md).
  uint64_t max_triangles = 10'000'000;
  uint64_t max_vertices = 30'000'000;
  uint64_t max_instances = 1'000'000;
  uint64_t max_entities = 50'000'000;
  // Pixels of all the images one load decodes (textures, the environment map), charged from each
  // image's header before its pixels are decoded (PixelAllowance, image_file.h): one image of the
  // side limit (16384²), four of 8192², or sixty-four of 2048²; at most 16 bytes a texel (float
  // RGB and alpha), 4 GiB.
  uint64_t max_texels = uint64_t(1) << 28;

  // "" if `e` is within every budget, else the first one it exceeds, as
  // "expands to up to N triangles, more than the budget of B (SceneBudget::max_triangles, docs/security.md)".
  std::string Exceeded(const SceneExpansion& e) const {
    auto over = [](uint64_t count, uint64_t budget, const char* what, const char* field, bool bound) {
      return "expands to " + std::string(bound ? "up to " : "") +
             (count == std::numeric_limits<uint64_t>::max() ? "more than 2^64" : std::to_string(count)) +
             " " + what + ", more than the budget of " + std::to_string(budget) + " (SceneBudget::" + field +
             ", docs/security.md)";
    };
    if (e.instances > max_instances)
      return over(e.instances, max_instances, "array instances", "max_instances", false);
    if (e.entities > max_entities) return over(e.entities, max_entities, "entities", "max_entities", false);
    if (e.triangles > max_triangles)
      return over(e.triangles, max_triangles, "triangles", "max_triangles", true);
    if (e.vertices > max_vertices) return over(e.vertices, max_vertices, "vertices", "max_vertices", true);
    return "";
  }
};

}  // namespace pf
