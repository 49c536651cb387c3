// glTF 2.0 parsing and the extension policy (gltf_document.h).
#include "common/scene/gltf_document.h"

#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <string_view>

#include "common/core/error.h"
#include "common/scene/scene_reference.h"

namespace pf {

namespace {

// What the loader reads (gltf_loader.h: KHR_lights_punctual; gltf_materials.h: the material
// extensions). Everything else is named in a warning or refused.
constexpr std::array<std::string_view, 4> kSupportedExtensions = {
    "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_transmission",
    "KHR_materials_ior"};

namespace fs = std::filesystem;

// tinygltf's file access, confined to the scene's root (gltf_document.h): a file outside it
// "does not exist" for tinygltf, and the refusal is remembered for the error message.
struct Confinement {
  fs::path root;
  fs::path base_dir;
  std::string tinygltf_base;  // the folder tinygltf joins a uri to: the entry's path up to its last '/'
  std::string refused;        // the first refused reference and why
};

bool ConfinedFileExists(const std::string& path, void* user) {
  auto* c = static_cast<Confinement*>(user);
  // tinygltf looks for a uri next to the file, then in the working directory ("./" + uri). The
  // second is never the scene's: not found, and not a refusal to report either.
  if (!c->tinygltf_base.empty() && path.rfind("./", 0) == 0 && path.rfind(c->tinygltf_base + "/", 0) != 0)
    return false;
  const fs::path rel = fs::absolute(fs::path(path))
                           .lexically_normal()
                           .lexically_relative(fs::absolute(c->base_dir).lexically_normal());
  const std::string problem = SceneReferenceProblem(c->root, c->base_dir, rel.generic_string(), nullptr);
  if (!problem.empty()) {
    if (c->refused.empty()) c->refused = QuoteReference(rel.generic_string()) + " " + problem;
    return false;
  }
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

// No shell expansion (tinygltf's default runs wordexp on the name).
std::string VerbatimPath(const std::string& path, void*) {
  return path;
}

bool ReadConfinedFile(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                      void* user) {
  if (!ConfinedFileExists(path, user)) {
    if (err) *err += "cannot read " + path;
    return false;
  }
  return tinygltf::ReadWholeFile(out, err, path, nullptr);
}

// Images are kept as read (their encoded bytes in Image::image), not decoded: the textures a
// material uses are decoded by gltf_textures.cpp, after their size is checked.
// An image in a buffer view is not copied here: tinygltf hands over the view's bytes without
// checking that the view lies inside its buffer, so gltf_textures.cpp reads it after that check.
bool KeepImageUndecoded(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void*) {
  if (image && image->bufferView < 0 && bytes && size > 0) image->image.assign(bytes, bytes + size);
  return true;
}

// A uri as tinygltf decodes it before opening the file ('+' is a space, %XX a byte).
std::string PercentDecoded(const std::string& uri) {
  std::string out;
  for (size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '+') {
      out += ' ';
    } else if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
               std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
      out += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

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

std::vector<std::string> GltfFileReferences(const std::string& json_text) {
  std::vector<std::string> refs;
  const nlohmann::json j = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object()) return refs;
  for (const char* key : {"buffers", "images"}) {
    const auto it = j.find(key);
    if (it == j.end() || !it->is_array()) continue;
    for (const nlohmann::json& item : *it) {
      if (!item.is_object() || !item.contains("uri") || !item["uri"].is_string()) continue;
      const std::string uri = item["uri"].get<std::string>();
      if (uri.rfind("data:", 0) != 0 && !uri.empty()) refs.push_back(PercentDecoded(uri));
    }
  }
  return refs;
}

GltfDocument::GltfDocument() : model(std::make_unique<tinygltf::Model>()) {}
GltfDocument::GltfDocument(GltfDocument&&) noexcept = default;
GltfDocument& GltfDocument::operator=(GltfDocument&&) noexcept = default;
GltfDocument::~GltfDocument() = default;

GltfDocument ReadGltfDocument(const std::filesystem::path& path, const std::filesystem::path& root) {
  GltfDocument doc;
  doc.file = path.filename().string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(SourceLocation{doc.file, 0}, "no such file");

  Confinement confinement;
  confinement.base_dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  confinement.root = root.empty() ? confinement.base_dir : root;
  const std::string entry = path.string();
  if (const size_t slash = entry.find_last_of("/\\"); slash != std::string::npos)
    confinement.tinygltf_base = entry.substr(0, slash);
  tinygltf::TinyGLTF reader;
  reader.SetFsCallbacks(
      tinygltf::FsCallbacks{&ConfinedFileExists, &VerbatimPath, &ReadConfinedFile, nullptr, &confinement});
  reader.SetImageLoader(&KeepImageUndecoded, nullptr);
  std::string err;
  std::string warn;
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return char(std::tolower(ch)); });
  const bool ok = ext == ".glb" ? reader.LoadBinaryFromFile(doc.model.get(), &err, &warn, path.string())
                                : reader.LoadASCIIFromFile(doc.model.get(), &err, &warn, path.string());
  if (!ok || !err.empty()) {
    std::string why = err.empty() ? "cannot be read as glTF 2.0" : OneLine(err);
    if (!confinement.refused.empty()) why = confinement.refused + " (" + why + ")";
    throw InputError(SourceLocation{doc.file, 0}, why);
  }
  if (!confinement.refused.empty())
    doc.warnings.push_back(doc.file + ": " + confinement.refused + "; not read");
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
