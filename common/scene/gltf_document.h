#pragma once
// glTF 2.0 (.gltf / .glb) → a parsed document, through Debian's tinygltf (libtinygltf-dev 2.7).
//
// The first step of the glTF scene loader (gltf_loader.h): reading and validating the file.
//
// Packaging: Debian ships tinygltf as a shared library (libtinygltf.so, built with
// TINYGLTF_IMPLEMENTATION and stb_image from libstb), so no translation unit of pf defines
// TINYGLTF_IMPLEMENTATION; the header's defaults (nlohmann json, stb) must match the library's.
//
// Extensions (glTF 2.0 spec, §3.12): an extension this loader does not implement that the file
// lists in extensionsRequired is an InputError naming the file and the extension (Draco, KTX2 /
// basisu, meshopt, ...: the data cannot be read without it); one listed only in extensionsUsed
// gives one warning each (the file stays readable, the effect is lost).
//
// Files: external buffers and images (uri) resolve only inside the scene's root folder
// (scene_reference.h), never in the process's working directory (tinygltf's fallback); a refused
// buffer is an InputError naming the reference. Images are kept encoded (tinygltf::Image::image
// holds the file's bytes): gltf_textures.h decodes those a material uses, after checking their
// size, so a 100k x 100k texture costs its compressed bytes, not gigabytes.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace pf {

// Extensions the glTF scene loader reads (gltf_loader.h, gltf_materials.h).
bool IsSupportedGltfExtension(const std::string& name);

// The files a .gltf's JSON text refers to by relative uri (buffers and images; data: URIs and
// malformed JSON give none), percent-decoded, as written relative to the .gltf's folder. Scene
// bundles ship them (scene_bundle.h).
std::vector<std::string> GltfFileReferences(const std::string& json_text);

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
// InputError "file: reason" for a missing file, malformed JSON, a buffer that cannot be read or
// lies outside `root` (empty: the folder of `path`), or an unsupported required extension.
GltfDocument ReadGltfDocument(const std::filesystem::path& path, const std::filesystem::path& root = {});

}  // namespace pf
