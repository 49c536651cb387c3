#pragma once
// The per-scene manifest: a small JSON file that pairs a geometry file (MGF or OBJ) with
// cameras, punctual lights, an environment, suggested render settings, material overrides and notes. The
// format is documented in docs/scene-manifest.md; this header is its in-memory form. Parsing validates every
// key and reports type errors as InputError "file: key 'cameras[0].eye': expected 3 numbers" (JSON syntax
// errors carry the line). Unknown keys are warnings, not errors, so that newer manifests still load.

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "common/core/math.h"
#include "common/scene/scene.h"

namespace pf {

// A manifest's "materials" entry: changes applied to every material of that name after the
// geometry is loaded (scene_loader.cpp, ApplyMaterialOverride).
struct MaterialOverride {
  enum class Kind { kUnchanged, kDiffuse, kGlossy, kMirror, kGlass, kMetal, kRoughGlass };
  Kind kind = Kind::kUnchanged;
  std::optional<Rgb> diffuse;       // ρd
  std::optional<Rgb> specular;      // ρs
  std::optional<float> roughness;   // Ward α of ρs, or GGX roughness r (metal, rough-glass)
  std::optional<Rgb> transmission;  // τs
  std::optional<float> ior;
  std::optional<Rgb> emission;  // Le, W/(m²·sr)
};

// A "settings" value: numbers stay numbers; strings are kept as their text; anything else
// (booleans, arrays, objects, null) as its compact JSON text.
using SettingValue = std::variant<double, std::string>;

struct SceneManifest {
  std::filesystem::path file;       // the manifest itself
  std::string name;                 // "name", default: the manifest's file stem
  std::filesystem::path geometry;   // "geometry", resolved relative to the manifest's folder
  std::string geometry_reference;   // "geometry" as written (LoadScene confines it to the root)
  int geometry_line = 0;            // line of the "geometry" key (0 if not found)
  double scale = 1.0;               // "scale": multiplies positions and camera points
  int scale_line = 0;               // line of the "scale" key (0 if absent or not found)
  std::vector<CameraSpec> cameras;  // "cameras", in file order
  CameraPath camera_path;           // "camera_path": keys by frame (camera_path.h)
  std::map<std::string, SettingValue> settings;
  std::map<std::string, MaterialOverride> materials;
  std::vector<PunctualLight> lights;       // "lights", in file order (ids are given by LoadScene)
  std::optional<Environment> environment;  // "environment"; its image is read by LoadScene
  std::string notes;
  std::vector<std::string> warnings;  // "file: reason"
};

// Reads and validates a manifest. Throws InputError (missing file, JSON syntax error with its
// line, a key of the wrong type or out of range, naming the key path).
SceneManifest LoadManifest(const std::filesystem::path& path);
// The same from text; `file` is used for messages and to resolve "geometry".
SceneManifest ParseManifest(const std::string& text, const std::filesystem::path& file);

}  // namespace pf
