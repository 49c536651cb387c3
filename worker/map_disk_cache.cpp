#include "worker/map_disk_cache.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "common/core/atomic_file.h"
#include "common/photon/map_key.h"

namespace pf::worker {
namespace fs = std::filesystem;

namespace {

constexpr std::string_view kSuffix = ".pfmaps";

}  // namespace

MapDiskCache::MapDiskCache(fs::path dir, uint64_t max_bytes) : dir_(std::move(dir)), max_bytes_(max_bytes) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec))
    if (IsTemporaryName(e.path().filename().string())) fs::remove(e.path(), ec);
}

fs::path MapDiskCache::PathOf(const std::string& key) const {
  if (!MapKey::IsAddress(key)) throw std::invalid_argument("map cache: malformed key '" + key + "'");
  return dir_ / (key + std::string(kSuffix));
}

std::optional<std::string> MapDiskCache::Get(const std::string& key) {
  const fs::path path = PathOf(key);
  std::lock_guard lock(mu_);
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  std::error_code ec;
  fs::last_write_time(path, fs::file_time_type::clock::now(), ec);  // most recently used
  return bytes;
}

void MapDiskCache::Put(const std::string& key, std::string_view bytes) {
  const fs::path path = PathOf(key);
  if (bytes.size() > max_bytes_) return;
  std::lock_guard lock(mu_);
  // Not fsynced (atomic_file.h, Durability): every read of the cache checks the map's digest and
  // a bad file is removed and fetched again, while the flush of the default farm job's 12.4 MB
  // map delayed each worker's first render by ~25 ms (its log: "fetched" to "rendering").
  WriteFileAtomically(path, bytes, Durability::kVolatile);
  EvictLocked();
}

void MapDiskCache::Remove(const std::string& key) {
  const fs::path path = PathOf(key);
  std::lock_guard lock(mu_);
  std::error_code ec;
  fs::remove(path, ec);
}

uint64_t MapDiskCache::total_bytes() {
  std::lock_guard lock(mu_);
  uint64_t total = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec))
    if (e.path().extension() == kSuffix) total += e.file_size(ec);
  return total;
}

void MapDiskCache::EvictLocked() {
  struct File {
    fs::path path;
    fs::file_time_type used;
    uint64_t bytes;
  };
  std::vector<File> files;
  uint64_t total = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec)) {
    if (e.path().extension() != kSuffix) continue;
    File f{e.path(), e.last_write_time(ec), e.file_size(ec)};
    total += f.bytes;
    files.push_back(std::move(f));
  }
  std::sort(files.begin(), files.end(), [](const File& a, const File& b) { return a.used < b.used; });
  for (const File& f : files) {
    if (total <= max_bytes_) break;
    fs::remove(f.path, ec);
    total -= f.bytes;
    spdlog::info("map cache: evicted {} ({} bytes; limit {} bytes)", f.path.filename().string(), f.bytes,
                 max_bytes_);
  }
}

}  // namespace pf::worker
