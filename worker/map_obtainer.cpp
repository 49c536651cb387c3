#include "worker/map_obtainer.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "common/core/error.h"
#include "common/photon/photon_maps_bytes.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int kFetchAttempts = 3;
// Before anything is measured: tracing + balancing 1M photons takes ~1.1 s on one core of the
// development VM (docs/results/farm.md), loopback moves ~200 MB/s through gRPC.
constexpr double kDefaultSecondsPerPhoton = 1.1e-6;
constexpr double kDefaultBytesPerSecond = 200e6;

std::string Short(const std::string& key) {
  return key.substr(0, 12);
}

// The bytes must be the map the coordinator named, and the map that of the task's seed.
std::shared_ptr<const PhotonMaps> Usable(const std::string& bytes, const v1::MapRef& ref, uint64_t map_seed) {
  std::optional<PhotonMaps> maps = ReadNamedPhotonMaps(bytes, ref.digest(), map_seed);
  return maps ? std::make_shared<const PhotonMaps>(std::move(*maps)) : nullptr;
}

}  // namespace

MapObtainer::MapObtainer(CoordinatorClient& client, const WorkerOptions& options)
    : client_(client),
      faults_(options.faults),
      memory_(std::make_shared<PhotonMapCache>(options.map_cache_capacity)),
      disk_(options.map_cache_dir.empty() ? options.cache_dir / "maps" : options.map_cache_dir,
            options.map_cache_bytes) {}

void MapObtainer::ObserveTracing(uint64_t photons, double seconds) {
  if (photons == 0 || !(seconds > 0)) return;
  const double measured = seconds / double(photons);
  seconds_per_photon_ = seconds_per_photon_ > 0 ? 0.5 * (seconds_per_photon_ + measured) : measured;
}

bool MapObtainer::InMemory(const std::string& cache_key, const v1::MapRef& ref, const std::string& ctx) {
  if (Forget(cache_key, ref.digest()))
    spdlog::warn("map {} for {}: the one in memory was fetched under another digest: obtained again",
                 Short(ref.map_key()), ctx);
  return memory_->Find(cache_key) != nullptr;
}

std::optional<TaskEnd> MapObtainer::Obtain(const std::string& cache_key, const v1::MapRef& ref,
                                           const std::string& ctx, uint64_t photons, uint64_t map_seed) {
  if (FromDisk(cache_key, ref, ctx, map_seed)) return std::nullopt;
  // Trace or fetch (docs/farm.md, "Photon maps traced once"): photons × measured seconds per photon against
  // bytes ÷ measured bandwidth.
  const double spp = seconds_per_photon_ > 0 ? seconds_per_photon_ : kDefaultSecondsPerPhoton;
  const double bps = bytes_per_second_ > 0 ? bytes_per_second_ : kDefaultBytesPerSecond;
  const double trace_s = double(photons) * spp;
  const double fetch_s = double(ref.bytes()) / bps;
  const bool fetch = fetch_s <= trace_s;
  spdlog::info(
      "map {} for {}: {}: fetch {} bytes / {:.1f} MB/s{} = {:.3f} s vs trace {} photons x {:.3f} us{} = "
      "{:.3f} s",
      Short(ref.map_key()), ctx, fetch ? "fetch" : "trace", ref.bytes(), bps / 1e6,
      bytes_per_second_ > 0 ? " (measured)" : " (default)", fetch_s, photons, spp * 1e6,
      seconds_per_photon_ > 0 ? " (measured)" : " (default)", trace_s);
  if (!fetch) return std::nullopt;
  if (faults_) faults_->At("fetch", ctx);
  return Fetch(cache_key, ref, ctx, map_seed);
}

bool MapObtainer::FromDisk(const std::string& cache_key, const v1::MapRef& ref, const std::string& ctx,
                           uint64_t map_seed) {
  try {
    if (std::optional<std::string> bytes = disk_.Get(ref.map_key())) {
      std::shared_ptr<const PhotonMaps> maps;
      try {
        maps = Usable(*bytes, ref, map_seed);
      } catch (const InputError& e) {
        spdlog::warn("map {} on disk: {}: removed", Short(ref.map_key()), e.what());
      }
      if (maps) {
        memory_->Insert(cache_key, std::move(maps));
        NoteFetched(cache_key, ref.digest());
        spdlog::info("map {} for {} from disk cache ({} bytes)", Short(ref.map_key()), ctx, bytes->size());
        ++from_disk_;
        return true;
      }
      disk_.Remove(ref.map_key());
    }
  } catch (const std::exception& e) {
    spdlog::warn("map disk cache {}: {}", disk_.dir().string(), e.what());
  }
  return false;
}

std::optional<TaskEnd> MapObtainer::Fetch(const std::string& cache_key, const v1::MapRef& ref,
                                          const std::string& ctx, uint64_t map_seed) {
  for (int attempt = 1; attempt <= kFetchAttempts; ++attempt) {
    const Clock::time_point t0 = Clock::now();
    try {
      const std::string bytes = client_.FetchMap(ref, ctx);
      const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      std::shared_ptr<const PhotonMaps> maps = Usable(bytes, ref, map_seed);
      if (!maps) throw TransferError("map " + Short(ref.map_key()) + ": digest or seed mismatch: refused");
      memory_->Insert(cache_key, std::move(maps));
      NoteFetched(cache_key, ref.digest());
      if (seconds > 0) {
        const double measured = double(bytes.size()) / seconds;
        bytes_per_second_ = bytes_per_second_ > 0 ? 0.5 * (bytes_per_second_ + measured) : measured;
      }
      spdlog::info("map {} for {} fetched: {} bytes in {:.3f} s (attempt {})", Short(ref.map_key()), ctx,
                   bytes.size(), seconds, attempt);
      try {
        disk_.Put(ref.map_key(), bytes);
      } catch (const std::exception& e) {
        spdlog::warn("map disk cache {}: {}", disk_.dir().string(), e.what());
      }
      ++fetched_;
      return std::nullopt;
    } catch (const TransferError& e) {
      spdlog::warn("{} (attempt {} of {}){}", e.what(), attempt, kFetchAttempts,
                   attempt < kFetchAttempts ? ": fetching again" : "");
    } catch (const InputError& e) {
      spdlog::warn("map {} for {}: {} (attempt {} of {})", Short(ref.map_key()), ctx, e.what(), attempt,
                   kFetchAttempts);
    } catch (const RpcError& e) {
      if (IsConnectionError(e.status())) {
        spdlog::warn("FetchMap for {}: {}; the lease will expire", ctx, StatusToString(e.status()));
        return TaskEnd::Unreachable();
      }
      spdlog::warn("FetchMap for {}: {}", ctx, StatusToString(e.status()));
      break;
    }
  }
  spdlog::warn("map {} for {}: not fetched: traced here instead", Short(ref.map_key()), ctx);
  return std::nullopt;
}

void MapObtainer::NoteFetched(const std::string& cache_key, const std::string& digest) {
  std::lock_guard lock(mutex_);
  fetched_maps_[cache_key] = digest;
}

bool MapObtainer::Forget(const std::string& cache_key, const std::string& digest) {
  {
    std::lock_guard lock(mutex_);
    auto it = fetched_maps_.find(cache_key);
    if (it == fetched_maps_.end()) return false;
    if (!digest.empty() && it->second == digest) return false;  // the map the task names
    fetched_maps_.erase(it);
  }
  // A map traced here since is dropped too: it costs a trace, never a wrong image.
  memory_->Erase(cache_key);
  return true;
}

}  // namespace pf::worker
