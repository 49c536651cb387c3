#pragma once
// Stored scene bundles: `<data-dir>/scenes/<hash>/` holds the bundle's files as uploaded; the
// `scenes` table (SqliteStore) holds what loading it once told us (entry, triangles, lights, the
// scene's camera); an in-memory index answers SubmitJob's lookups.
//
// Upload validates before storing: limits (kMaxBundleBytes / kMaxBundleFiles →
// RESOURCE_EXHAUSTED), path rules (bundle.files[i].path, INVALID_ARGUMENT), then loads the scene
// from a temporary folder (a malformed scene is INVALID_ARGUMENT with the loader's file:line,
// named relative to the bundle) and only then renames the folder to its hash. Idempotent: the
// same bundle again returns the stored scene without loading it.

#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>

#include "common/scene/scene_bundle.h"
#include "server/clock.h"
#include "server/store/scene_catalog.h"
#include "server/store/sqlite_store.h"

namespace pf::server {

struct UploadResult {
  SceneInfo info;
  bool created = false;  // false: the bundle was already stored
};

class SceneStore final : public SceneCatalog {
 public:
  SceneStore(std::filesystem::path scenes_dir, SqliteStore& db, const Clock& clock);

  // Rebuilds the index from the database; rows whose folder is missing are skipped (logged).
  void LoadIndex();

  UploadResult Upload(const SceneBundle& bundle);
  std::optional<SceneInfo> FindScene(const std::string& hash) const override;
  // The stored files of a scene: (bundle path, file on disk), sorted by bundle path (the order
  // FetchScene streams them in). NotFoundError naming scene_hash if unknown.
  std::vector<std::pair<std::string, std::filesystem::path>> ListFiles(const std::string& hash) const;
  // The stored files of a scene, read into memory. NotFoundError naming scene_hash if unknown.
  SceneBundle ReadBundle(const std::string& hash) const;
  std::filesystem::path DirectoryOf(const std::string& hash) const { return dir_ / hash; }
  // The file content bytes of every stored bundle (the budget scene_bytes_total, server/rpc/budgets.h).
  uint64_t StoredBytes() const;

 private:
  std::filesystem::path dir_;
  SqliteStore& db_;
  const Clock& clock_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, SceneInfo> index_;
};

}  // namespace pf::server
