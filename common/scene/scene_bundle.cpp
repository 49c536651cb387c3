#include "common/scene/scene_bundle.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "common/core/error.h"
#include "common/core/sha256.h"
#include "common/scene/gltf_document.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_loader.h"
#include "common/scene/scene_reference.h"

namespace pf {
namespace fs = std::filesystem;

namespace {

constexpr std::string_view kHashDomain = "photonfarm-bundle-v1\n";

std::string ReadWholeFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SystemError(path.string() + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw SystemError(path.string() + ": read failed");
  return std::move(ss).str();
}

std::string LimitMessage() {
  return "the bundle limit is " + std::to_string(kMaxBundleBytes >> 20) + " MiB of file content and " +
         std::to_string(kMaxBundleFiles) + " files";
}

// "" if `path` is a valid bundle path, else the reason.
std::string PathProblem(const std::string& path) {
  if (path.empty()) return "empty path";
  if (path.size() > kMaxBundlePathBytes)
    return "path longer than " + std::to_string(kMaxBundlePathBytes) + " bytes";
  if (path.find('\0') != std::string::npos) return "path contains a NUL byte";
  for (const char ch : path)
    if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) return "path contains a control character";
  if (path.find('\\') != std::string::npos) return "path contains a backslash (use '/')";
  if (path.front() == '/') return "absolute path (must be relative to the bundle root)";
  size_t begin = 0;
  while (begin <= path.size()) {
    const size_t end = std::min(path.find('/', begin), path.size());
    const std::string_view part(path.data() + begin, end - begin);
    if (part.empty()) return "empty path component";
    if (part == "." || part == "..") {
      // Built with append: GCC 12's -Wrestrict misfires on "'" + std::string(part) + ...
      std::string message(1, '\'');
      message.append(part).append("' component (paths stay inside the bundle)");
      return message;
    }
    begin = end + 1;
  }
  return "";
}

// The bundle hash's hasher: SHA-256 (common/core/sha256.h) plus little-endian u64 fields.
class Sha256 {
 public:
  void Update(std::string_view bytes) { hasher_.Update(bytes); }
  void UpdateU64(uint64_t v) {
    unsigned char le[8];
    for (int i = 0; i < 8; ++i) le[i] = static_cast<unsigned char>(v >> (8 * i));
    Update(std::string_view(reinterpret_cast<const char*>(le), 8));
  }
  std::string HexDigest() { return hasher_.HexDigest(); }

 private:
  Sha256Hasher hasher_;
};

// Replaces every occurrence of `from` in `s` by `to`.
std::string ReplaceAll(std::string s, const std::string& from, const std::string& to) {
  if (from.empty()) return s;
  for (size_t pos = s.find(from); pos != std::string::npos; pos = s.find(from, pos + to.size()))
    s.replace(pos, from.size(), to);
  return s;
}

}  // namespace

uint64_t SceneBundle::TotalBytes() const {
  uint64_t total = 0;
  for (const auto& [path, content] : files) total += content.size();
  return total;
}

namespace {
// Renders kept next to a scene (references, previews) are outputs, never inputs, so shipping
// them would only cost upload time; an image a glTF of the folder refers to is an input
// (GltfReferencedFiles).
std::string LowerExtension(const fs::path& rel) {
  std::string ext = rel.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

bool IsRenderedImage(const fs::path& rel) {
  const std::string ext = LowerExtension(rel);
  return ext == ".exr" || ext == ".png";
}

// The JSON text of a .gltf, or of a .glb's first chunk (glTF 2.0 spec, §4.4: a 12-byte header,
// then a chunk of u32le length, u32le type "JSON", the text); "" for anything else.
std::string GltfJsonText(const fs::path& rel, const std::string& content) {
  const std::string ext = LowerExtension(rel);
  if (ext == ".gltf") return content;
  if (ext != ".glb" || content.size() < 20 || content.compare(0, 4, "glTF") != 0) return {};
  uint32_t length = 0;
  for (int k = 0; k < 4; ++k) length |= uint32_t(static_cast<unsigned char>(content[12 + k])) << (8 * k);
  if (content.compare(16, 4, "JSON") != 0 || length > content.size() - 20) return {};
  return content.substr(20, length);
}

// The bundle paths of every file a .gltf or .glb among `listed` (relative to the scene folder `root`)
// refers to by uri. A reference that leaves the folder names no listed file and so adds nothing.
std::set<std::string> GltfReferencedFiles(const std::vector<fs::path>& listed, const fs::path& root) {
  std::set<std::string> referenced;
  for (const fs::path& rel : listed) {
    std::error_code ec;
    // One over the limit fails the collection anyway; it is not read twice for that.
    const std::string ext = LowerExtension(rel);
    if ((ext != ".gltf" && ext != ".glb") || !(fs::file_size(root / rel, ec) <= kMaxBundleBytes)) continue;
    for (const std::string& ref : GltfFileReferences(GltfJsonText(rel, ReadWholeFile(root / rel))))
      referenced.insert((rel.parent_path() / fs::path(ref)).lexically_normal().generic_string());
  }
  return referenced;
}

// The bundle paths of the image files the .mtl files among `listed` name in map statements
// (map_Kd and the others: obj_loader.cpp reads map_Kd and warns about the rest, so a scene renders
// the same from its bundle). The file name is the statement's last word (options come first),
// resolved from the .mtl's folder and from the scene folder, as obj_loader.cpp may resolve it.
std::set<std::string> MtlReferencedFiles(const std::vector<fs::path>& listed, const fs::path& root) {
  std::set<std::string> referenced;
  for (const fs::path& rel : listed) {
    std::error_code ec;
    if (LowerExtension(rel) != ".mtl" || !(fs::file_size(root / rel, ec) <= kMaxBundleBytes)) continue;
    std::istringstream text(ReadWholeFile(root / rel));
    for (std::string line; std::getline(text, line);) {
      std::istringstream words(line);
      std::string keyword, word, last;
      words >> keyword;
      const bool map = keyword.rfind("map_", 0) == 0 || keyword == "bump" || keyword == "disp" ||
                       keyword == "decal" || keyword == "refl" || keyword == "norm";
      if (!map) continue;
      while (words >> word) last = word;
      if (last.empty()) continue;
      referenced.insert((rel.parent_path() / fs::path(last)).lexically_normal().generic_string());
      referenced.insert(fs::path(last).lexically_normal().generic_string());
    }
  }
  return referenced;
}

// The images a manifest entry reads (its "environment.file"), relative to the entry's folder:
// inputs, shipped whatever their extension. A manifest that does not parse names none: loading
// the bundle reports it.
std::set<std::string> InputImages(const fs::path& entry) {
  std::set<std::string> images;
  if (LowerExtension(entry) != ".json") return images;
  try {
    const SceneManifest manifest = LoadManifest(entry);
    if (manifest.environment && !manifest.environment->file.empty())
      images.insert(fs::path(manifest.environment->file).lexically_normal().generic_string());
  } catch (const InputError&) {
  }
  return images;
}

}  // namespace

SceneBundle CollectBundle(const fs::path& entry) {
  std::error_code ec;
  if (!fs::is_regular_file(entry, ec))
    throw InputError(SourceLocation{entry.string(), 0}, "scene file not found (or not a regular file)");
  const fs::path root = entry.has_parent_path() ? entry.parent_path() : fs::path(".");
  SceneBundle bundle;
  bundle.entry = entry.filename().generic_string();
  std::vector<fs::path> listed;  // relative to root
  for (fs::recursive_directory_iterator it(root, fs::directory_options::none, ec), end; !ec && it != end;
       it.increment(ec)) {
    if (it->is_regular_file(ec)) listed.push_back(it->path().lexically_relative(root));
  }
  if (ec) throw SystemError(root.string() + ": cannot list the scene folder: " + ec.message());
  std::set<std::string> referenced = GltfReferencedFiles(listed, root);
  referenced.merge(InputImages(entry));
  referenced.merge(MtlReferencedFiles(listed, root));
  uint64_t total = 0;
  for (const fs::path& rel : listed) {
    if (IsRenderedImage(rel) && !referenced.count(rel.generic_string())) continue;
    const uint64_t size = fs::file_size(root / rel, ec);
    if (ec) throw SystemError((root / rel).string() + ": cannot read its size: " + ec.message());
    total += size;
    if (total > kMaxBundleBytes || bundle.files.size() + 1 > kMaxBundleFiles)
      throw InputError(SourceLocation{root.string(), 0},
                       "the scene folder holds more than the bundle limit (" + LimitMessage() +
                           "); keep each scene in its own folder");
    bundle.files.emplace_back(rel.generic_string(), ReadWholeFile(root / rel));
  }
  std::sort(bundle.files.begin(), bundle.files.end());
  ValidateBundle(bundle);
  return bundle;
}

std::string BundleHash(const SceneBundle& bundle) {
  std::vector<const std::pair<std::string, std::string>*> sorted;
  sorted.reserve(bundle.files.size());
  for (const auto& f : bundle.files) sorted.push_back(&f);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->first < b->first; });
  Sha256 sha;
  sha.Update(kHashDomain);
  sha.UpdateU64(bundle.entry.size());
  sha.Update(bundle.entry);
  sha.UpdateU64(sorted.size());
  for (const auto* f : sorted) {
    sha.UpdateU64(f->first.size());
    sha.Update(f->first);
    sha.UpdateU64(f->second.size());
    sha.Update(f->second);
  }
  return sha.HexDigest();
}

void ValidateBundle(const SceneBundle& bundle) {
  if (bundle.files.size() > kMaxBundleFiles)
    throw InputError("bundle.files: " + std::to_string(bundle.files.size()) + " files exceed " +
                     LimitMessage());
  if (bundle.TotalBytes() > kMaxBundleBytes)
    throw InputError("bundle.files: " + std::to_string(bundle.TotalBytes()) + " bytes exceed " +
                     LimitMessage());
  std::set<std::string_view> seen;
  for (size_t i = 0; i < bundle.files.size(); ++i) {
    const std::string& path = bundle.files[i].first;
    const std::string problem = PathProblem(path);
    const std::string field = "bundle.files[" + std::to_string(i) + "].path " + QuoteReference(path);
    if (!problem.empty()) throw InputError(field + ": " + problem);
    if (!seen.insert(path).second) throw InputError(field + ": duplicate path");
  }
  // A path cannot be a file and a folder at once ("a" and "a/b"): the bundle could not be
  // written to disk, and which one wins would depend on the order of writing.
  for (size_t i = 0; i < bundle.files.size(); ++i) {
    const std::string& path = bundle.files[i].first;
    for (size_t slash = path.find('/'); slash != std::string::npos; slash = path.find('/', slash + 1)) {
      if (seen.count(std::string_view(path).substr(0, slash)))
        throw InputError("bundle.files[" + std::to_string(i) + "].path " + QuoteReference(path) + ": " +
                         QuoteReference(path.substr(0, slash)) +
                         " is also a file of the bundle (a path cannot be a file and a folder)");
    }
  }
  const std::string entry_problem = PathProblem(bundle.entry);
  if (!entry_problem.empty())
    throw InputError("bundle.entry " + QuoteReference(bundle.entry) + ": " + entry_problem);
  if (!seen.count(bundle.entry))
    throw InputError("bundle.entry " + QuoteReference(bundle.entry) + ": not among the bundle's files");
}

void WriteBundle(const SceneBundle& bundle, const fs::path& dir) {
  ValidateBundle(bundle);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw SystemError(dir.string() + ": cannot create directory: " + ec.message());
  for (const auto& [path, content] : bundle.files) {
    const fs::path target = dir / fs::path(path);
    fs::create_directories(target.parent_path(), ec);
    if (ec) throw SystemError(target.parent_path().string() + ": cannot create directory: " + ec.message());
    std::ofstream out(target, std::ios::binary | std::ios::trunc);
    out.write(content.data(), std::streamsize(content.size()));
    out.close();
    if (!out) throw SystemError(target.string() + ": write failed");
  }
}

SceneDescription LoadBundle(const fs::path& dir, const std::string& entry) {
  const std::string problem = PathProblem(entry);
  if (!problem.empty()) throw InputError("bundle.entry " + QuoteReference(entry) + ": " + problem);
  // Messages name files as the client knows them: strip the storage directory.
  const std::string prefix = (dir / "").string();
  try {
    SceneDescription scene = LoadScene(dir / fs::path(entry), 0, dir);
    for (std::string& w : scene.warnings) w = ReplaceAll(std::move(w), prefix, "");
    scene.source = ReplaceAll(std::move(scene.source), prefix, "");
    return scene;
  } catch (const InputError& e) {
    // A budget stays a LimitError (RESOURCE_EXHAUSTED on the farm), the rest InputErrors.
    const bool limit = dynamic_cast<const LimitError*>(&e) != nullptr;
    const SourceLocation where{ReplaceAll(e.where().file, prefix, ""), e.where().line};
    const std::string reason = ReplaceAll(e.reason(), prefix, "");
    if (where.file.empty()) {
      if (limit) throw LimitError(reason);
      throw InputError(reason);
    }
    if (limit) throw LimitError(where, reason);
    throw InputError(where, reason);
  }
}

}  // namespace pf
