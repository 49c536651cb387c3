#pragma once
// glTF 2.0 (.gltf / .glb) → a parsed document, through Debian's tinygltf (libtinygltf-dev 2.7).
//
// This is the first step of the glTF scene loader: reading and validating the file. Turning the
// document into a SceneDescription (nodes, meshes, camera, KHR_lights_punctual, materials) is
// the next step and is not here yet.
//
// Packaging: Debian ships tinygltf as a shared library (libtinygltf.so, built with
// TINYGLTF_IMPLEMENTATION and stb_image from libstb), so no translation unit of pf defines
// TINYGLTF_IMPLEMENTATION; the header's defaults (nlohmann json, stb) must match the library's.
//
// Extensions (glTF 2.0 spec, §3.12): an extension this loader does not implement that the file
// lists in extensionsRequired is an InputError naming the file and the extension (Draco, KTX2 /
// basisu, meshopt, ...: the data cannot be read without it); one listed only in extensionsUsed
// gives one warning each (the file stays readable, the effect is lost).

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace pf {

// Extensions the glTF scene loader understands (it will read them once it exists in full).
bool IsSupportedGltfExtension(const std::string& name);

struct GltfDocument {
  std::unique_ptr<tinygltf::Model> model;
  std::string file;                   // the file name used in messages ("scene.gltf")
  std::vector<std::string> warnings;  // "scene.gltf: extension 'X' is not supported; ignored"
  GltfDocument();
  GltfDocument(GltfDocument&&) noexcept;
  GltfDocument& operator=(GltfDocument&&) noexcept;
  ~GltfDocument();
};

// Reads a .gltf (JSON, buffers by uri or base64 data URI) or a .glb (binary container). Throws
// InputError "file: reason" for a missing file, malformed JSON, a buffer that cannot be read,
// or an unsupported required extension.
GltfDocument ReadGltfDocument(const std::filesystem::path& path);

}  // namespace pf
