// glTF 2.0 parsing and the extension policy (gltf_document.h).
#include "common/scene/gltf_document.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <string_view>

#include "common/core/error.h"

namespace pf {

namespace {

// What the loader implements or will implement next (KHR_lights_punctual: point/spot/directional;
// KHR_materials_emissive_strength: Le scale). Everything else is named in a warning or refused.
constexpr std::array<std::string_view, 2> kSupportedExtensions = {"KHR_lights_punctual",
                                                                  "KHR_materials_emissive_strength"};

// tinygltf joins several messages with newlines; one line per message keeps the CLI output tidy.
std::string OneLine(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  std::replace(text.begin(), text.end(), '\n', ';');
  return text;
}

}  // namespace

bool IsSupportedGltfExtension(const std::string& name) {
  return std::find(kSupportedExtensions.begin(), kSupportedExtensions.end(), name) !=
         kSupportedExtensions.end();
}

GltfDocument::GltfDocument() : model(std::make_unique<tinygltf::Model>()) {}
GltfDocument::GltfDocument(GltfDocument&&) noexcept = default;
GltfDocument& GltfDocument::operator=(GltfDocument&&) noexcept = default;
GltfDocument::~GltfDocument() = default;

GltfDocument ReadGltfDocument(const std::filesystem::path& path) {
  GltfDocument doc;
  doc.file = path.filename().string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(SourceLocation{doc.file, 0}, "no such file");

  tinygltf::TinyGLTF reader;
  std::string err;
  std::string warn;
  const bool binary = path.extension() == ".glb";
  const bool ok = binary ? reader.LoadBinaryFromFile(doc.model.get(), &err, &warn, path.string())
                         : reader.LoadASCIIFromFile(doc.model.get(), &err, &warn, path.string());
  if (!ok || !err.empty()) {
    throw InputError(SourceLocation{doc.file, 0}, err.empty() ? "cannot be read as glTF 2.0" : OneLine(err));
  }
  if (!warn.empty()) doc.warnings.push_back(doc.file + ": " + OneLine(warn));

  const tinygltf::Model& m = *doc.model;
  for (const std::string& ext : m.extensionsRequired) {
    if (!IsSupportedGltfExtension(ext)) {
      throw InputError(
          SourceLocation{doc.file, 0},
          "extensionsRequired: '" + ext + "' is not supported (the data cannot be read without it)");
    }
  }
  for (const std::string& ext : m.extensionsUsed) {
    const bool required = std::find(m.extensionsRequired.begin(), m.extensionsRequired.end(), ext) !=
                          m.extensionsRequired.end();
    if (!required && !IsSupportedGltfExtension(ext)) {
      doc.warnings.push_back(doc.file + ": extensionsUsed: '" + ext + "' is not supported; ignored");
    }
  }
  return doc;
}

}  // namespace pf
