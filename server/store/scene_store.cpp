#include "server/store/scene_store.h"

#include "proto/limits.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "common/core/atomic_file.h"
#include "common/core/error.h"
#include "common/photon/photon_tracer.h"
#include "common/scene/scene_loader.h"
#include "proto/convert.h"
#include "server/errors.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

std::string Join(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& l : lines) {
    if (!out.empty()) out += '\n';
    out += l;
  }
  return out;
}

std::vector<std::string> Split(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// The largest channel of any emitting material's Le: the scale of every radiance in the scene
// (the per-job result bound, server/jobs/job_spec.h). With area lights alone it bounds every
// radiance an energy-conserving BSDF reflects. A punctual light has no Le: a surface at distance
// d reflects ρ/π·I/d², unbounded as d → 0, so such a scene has no bound (-1, unknown: results are
// still checked for everything else, docs/farm.md "Results"). An environment's texels are not
// among the materials: no bound either.
double MaxEmission(const SceneDescription& scene) {
  if (!scene.punctual_lights.empty() || scene.environment) return -1;
  double m = 0;
  for (const Material& mat : scene.materials)
    for (int c = 0; c < 3; ++c) m = std::max(m, double(mat.emission[c]));
  return m;
}

// The columns of a scenes row that hold a SceneInfo's field as it is (the camera and the warnings
// are encoded), both ways.
template <typename From, typename To>
void CopyPlainColumns(const From& from, To& to) {
  to.hash = from.hash;
  to.entry = from.entry;
  to.triangles = from.triangles;
  to.lights = from.lights;
  to.max_emission = from.max_emission;
  to.caustic_paths = from.caustic_paths;
  to.bytes = from.bytes;
  to.files = from.files;
}

SceneInfo InfoFromRow(const SceneRow& row) {
  SceneInfo info;
  CopyPlainColumns(row, info);
  info.warnings = Split(row.warnings);
  photonfarm::v1::Camera cam;
  if (!cam.ParseFromString(row.default_camera)) throw SystemError("scenes table: bad camera of " + row.hash);
  info.camera = CameraFromProto(cam, "scene.camera");
  return info;
}

}  // namespace

SceneStore::SceneStore(fs::path scenes_dir, SqliteStore& db, const Clock& clock)
    : dir_(std::move(scenes_dir)), db_(db), clock_(clock) {
  fs::create_directories(dir_);
}

void SceneStore::LoadIndex() {
  // Folders of uploads interrupted by a crash.
  for (const auto& e : fs::directory_iterator(dir_)) {
    if (!IsTemporaryName(e.path().filename().string())) continue;
    std::error_code ec;
    fs::remove_all(e.path(), ec);
  }
  std::unordered_map<std::string, SceneInfo> index;
  for (const SceneRow& row : db_.LoadScenes()) {
    if (!fs::is_directory(dir_ / row.hash)) {
      spdlog::warn("scene {}: folder {} is missing; the scene is forgotten (upload it again)", row.hash,
                   (dir_ / row.hash).string());
      continue;
    }
    index[row.hash] = InfoFromRow(row);
  }
  std::lock_guard lock(mu_);
  index_ = std::move(index);
}

UploadResult SceneStore::Upload(const SceneBundle& bundle) {
  if (bundle.files.size() > kMaxBundleFiles || bundle.TotalBytes() > kMaxBundleBytes)
    throw LimitError("bundle.files: " + std::to_string(bundle.files.size()) + " files, " +
                     std::to_string(bundle.TotalBytes()) + " bytes exceed the bundle limit (" +
                     std::to_string(kMaxBundleBytes >> 20) + " MiB, " + std::to_string(kMaxBundleFiles) +
                     " files)");
  ValidateBundle(bundle);
  const std::string hash = BundleHash(bundle);
  if (std::optional<SceneInfo> known = FindScene(hash)) return {*known, false};

  const fs::path tmp = TemporarySibling(dir_ / hash);
  SceneDescription scene;
  try {
    WriteBundle(bundle, tmp);
    scene = LoadBundle(tmp, bundle.entry);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  SceneInfo info;
  info.hash = hash;
  info.entry = bundle.entry;
  info.triangles = scene.NumTriangles();
  info.lights = scene.num_lights;
  info.max_emission = MaxEmission(scene);
  info.caustic_paths = SceneNeedsCausticMap(scene) ? 1 : 0;
  info.bytes = bundle.TotalBytes();
  info.files = bundle.files.size();
  info.camera = scene.cameras.empty() ? DefaultCamera(scene) : scene.cameras.front();
  info.warnings = scene.warnings;

  // false: a concurrent upload of the same bundle won the race, or the folder survived a crash.
  PublishDirectory(tmp, dir_ / hash);
  SceneRow row;
  CopyPlainColumns(info, row);
  photonfarm::v1::Camera cam;
  CameraToProto(info.camera, &cam);
  row.default_camera = cam.SerializeAsString();
  row.warnings = Join(info.warnings);
  row.created_unix_ms = clock_.UnixMillis();
  db_.PutScene(row);
  {
    std::lock_guard lock(mu_);
    index_[hash] = info;
  }
  spdlog::info(
      "scene {}: stored ({} files, {} bytes, entry {}, {} triangles, {} lights, brightest Le {:.6g})", hash,
      info.files, info.bytes, info.entry, info.triangles, info.lights, info.max_emission);
  return {info, true};
}

std::optional<SceneInfo> SceneStore::FindScene(const std::string& hash) const {
  std::lock_guard lock(mu_);
  auto it = index_.find(hash);
  if (it == index_.end()) return std::nullopt;
  return it->second;
}

uint64_t SceneStore::StoredBytes() const {
  std::lock_guard lock(mu_);
  uint64_t bytes = 0;
  for (const auto& [hash, info] : index_) bytes += info.bytes;
  return bytes;
}

std::vector<std::pair<std::string, fs::path>> SceneStore::ListFiles(const std::string& hash) const {
  if (!FindScene(hash)) throw NotFoundError("scene_hash: unknown scene " + limits::Quote(hash));
  const fs::path root = dir_ / hash;
  std::vector<std::pair<std::string, fs::path>> files;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) files.emplace_back(e.path().lexically_relative(root).generic_string(), e.path());
  std::sort(files.begin(), files.end());
  return files;
}

SceneBundle SceneStore::ReadBundle(const std::string& hash) const {
  const std::optional<SceneInfo> info = FindScene(hash);
  if (!info) throw NotFoundError("scene_hash: unknown scene " + limits::Quote(hash));
  SceneBundle bundle;
  bundle.entry = info->entry;
  for (const auto& [path, file] : ListFiles(hash)) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw SystemError(file.string() + ": cannot read stored scene file");
    std::ostringstream ss;
    ss << in.rdbuf();
    bundle.files.emplace_back(path, std::move(ss).str());
  }
  return bundle;
}

}  // namespace pf::server
