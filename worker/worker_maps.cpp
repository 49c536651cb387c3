// pf-worker's part in photon maps traced once (docs/farm.md "Photon maps traced once"):
// tracing a piece of a map and uploading it, and getting a built map — from memory, from the disk
// cache, by FetchMap, or by tracing it here when the cost model says that is faster.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

#include "common/core/error.h"
#include "common/core/sha256.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "proto/convert.h"
#include "worker/worker.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

namespace {

constexpr size_t kPartBytes = size_t(1) << 20;  // parts of uploads (≤ 1 MiB, as the coordinator's)
constexpr int kFetchAttempts = 3;
// Before anything is measured: tracing + balancing 1M photons takes ~1.1 s on one core of the
// development VM (docs/results/farm.md), loopback moves ~200 MB/s through gRPC.
constexpr double kDefaultSecondsPerPhoton = 1.1e-6;
constexpr double kDefaultBytesPerSecond = 200e6;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool IsConnectionError(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE ||
         s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
}

std::string Short(const std::string& key) {
  return key.substr(0, 12);
}

// A transfer that failed its checks (a part's checksum, the map's digest): fetch again.
class TransferError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace

void Worker::ObserveTracing(uint64_t photons, double seconds) {
  if (photons == 0 || !(seconds > 0)) return;
  const double measured = seconds / double(photons);
  seconds_per_photon_ = seconds_per_photon_ > 0 ? 0.5 * (seconds_per_photon_ + measured) : measured;
}

Worker::Outcome Worker::RunTraceChunk(const v1::Task& task) {
  const v1::TraceChunk& piece = task.trace_chunk();
  const std::string ctx = "job=" + task.job_id() + " map=" + std::to_string(task.map_index()) +
                          " piece=" + std::to_string(piece.chunk_index()) + "/" +
                          std::to_string(piece.chunk_count()) + " attempt=" + std::to_string(task.attempt());
  {
    std::lock_guard lock(mutex_);
    ++counters_.leased;
  }
  JobRenderSettings settings;
  try {
    settings = SettingsFromProto(task.settings(), "task.settings");
    if (piece.photon_end() <= piece.photon_begin() || piece.photon_end() > settings.photons ||
        piece.photon_begin() % kPhotonTracingChunk != 0)
      throw InputError("task.trace_chunk: photons [" + std::to_string(piece.photon_begin()) + ", " +
                       std::to_string(piece.photon_end()) + ") are not a piece of the map");
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return Outcome::kDone;
  }
  spdlog::info("leased-piece {} photons=[{}, {}) lease={:.1f}s", ctx, piece.photon_begin(),
               piece.photon_end(), task.lease_seconds());
  // The lease is kept alive from here to the upload's end (scene fetch, trace, upload).
  LeaseKeeper keeper(this, task, ctx, NewExecution(1, task.lease_seconds()));
  std::shared_ptr<const SceneRuntime> scene;
  if (const std::optional<Outcome> ended = GetScene(task, ctx, &scene)) return *ended;
  SetState(State::kBuildingMap, ctx);
  std::string bytes;
  const Clock::time_point t0 = Clock::now();
  try {
    PhotonMapsOptions mo = settings.Resolved(scene->description).MapsOptions();
    mo.tracing.map_seed = task.map_seed();
    mo.tracing.threads = options_.threads;
    FaultPoint("trace", ctx);
    const PhotonChunk chunk =
        TracePhotonChunk(scene->accel, scene->lights, mo, piece.photon_begin(), piece.photon_end());
    // Tracing only; a piece is not balanced here. Building costs about as much again (§2.3), which
    // the cost model's rate includes when it is measured from whole maps.
    ObserveTracing(piece.photon_end() - piece.photon_begin(), 2.0 * SecondsSince(t0));
    bytes = SerializePhotonChunk(chunk);
    if (options_.faults) options_.faults->OnPiece(bytes);  // tests only: a malicious worker
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return Outcome::kDone;
  } catch (const std::exception& e) {
    Fail(task, ctx, e.what(), true);
    return Outcome::kDone;
  }
  const double trace_s = SecondsSince(t0);
  if (keeper.lost()) {
    spdlog::warn("abandoned {}: the piece lease is gone; not uploaded", ctx);
    std::lock_guard lock(mutex_);
    ++counters_.abandoned;
    return Outcome::kDone;
  }
  FaultPoint("upload", ctx);
  SetState(State::kReporting, ctx);
  grpc::Status status;
  const Clock::time_point t1 = Clock::now();
  const bool accepted = UploadChunk(task, ctx, bytes, &status);
  keeper.Stop();
  if (!status.ok()) {
    if (IsConnectionError(status)) {
      spdlog::warn("UploadPhotonChunk {}: {}; the lease will expire", ctx, StatusToString(status));
      return Outcome::kConnectionLost;
    }
    Fail(task, ctx, "upload refused: " + StatusToString(status), true);
    return Outcome::kDone;
  }
  spdlog::info("uploaded-piece {} accepted={} bytes={} trace_s={:.3f} upload_s={:.3f}", ctx,
               accepted ? "true" : "false", bytes.size(), trace_s, SecondsSince(t1));
  std::lock_guard lock(mutex_);
  ++counters_.chunks_traced;
  return Outcome::kDone;
}

bool Worker::UploadChunk(const v1::Task& task, const std::string& /*ctx*/, const std::string& bytes,
                         grpc::Status* status) {
  grpc::ClientContext cctx;
  PrepareContext(&cctx, options_.token, Seconds(options_.fetch_timeout_seconds));
  v1::UploadPhotonChunkResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::PhotonChunkPart>> writer(stub_->UploadPhotonChunk(&cctx, &response));
  size_t offset = 0;
  bool first = true;
  while (first || offset < bytes.size()) {
    v1::PhotonChunkPart part;
    if (first) {
      part.set_lease_id(task.lease_id());
      part.set_worker_id(options_.worker_id);
      part.set_total_bytes(bytes.size());
      part.set_digest(Sha256Hex(bytes));
    }
    const std::string_view data = std::string_view(bytes).substr(offset, kPartBytes);
    part.set_offset(offset);
    part.set_data(std::string(data));
    part.set_sha256(Sha256Hex(data));
    offset += data.size();
    first = false;
    if (!writer->Write(part)) break;  // the server ended the call: Finish says why
  }
  writer->WritesDone();
  *status = writer->Finish();
  return status->ok() && response.accepted();
}

std::string Worker::FetchMapBytes(const v1::MapRef& ref, const std::string& ctx) {
  grpc::ClientContext cctx;
  PrepareContext(&cctx, options_.token, Seconds(options_.fetch_timeout_seconds));
  v1::FetchMapRequest req;
  req.set_map_key(ref.map_key());
  std::unique_ptr<grpc::ClientReader<v1::MapBytes>> reader(stub_->FetchMap(&cctx, req));
  std::string bytes;
  bytes.reserve(size_t(std::min<uint64_t>(ref.bytes(), uint64_t(1) << 34)));
  v1::MapBytes part;
  uint32_t index = 0;
  std::string refused;
  while (reader->Read(&part)) {
    std::string data = part.data();
    if (options_.faults) options_.faults->OnMapPart(data, index, ref.map_key());  // tests only
    if (refused.empty()) {
      if (part.offset() != bytes.size())
        refused = "part " + std::to_string(index) + " at offset " + std::to_string(part.offset()) +
                  ", expected " + std::to_string(bytes.size());
      else if (Sha256Hex(data) != part.sha256())
        refused = "part " + std::to_string(index) + ": checksum mismatch";
      else if (part.total_bytes() != ref.bytes() || part.digest() != ref.digest())
        refused = "the coordinator now holds another map under this key";
      if (!refused.empty()) cctx.TryCancel();  // nothing more of this transfer is used
    }
    if (refused.empty()) bytes += data;
    ++index;
  }
  const grpc::Status status = reader->Finish();
  if (!refused.empty()) {
    {
      std::lock_guard lock(mutex_);
      ++counters_.map_parts_refused;
    }
    throw TransferError("map " + Short(ref.map_key()) + " for " + ctx + ": " + refused + ": refused");
  }
  if (!status.ok()) throw RpcError(status);
  if (bytes.size() != ref.bytes())
    throw TransferError("map " + Short(ref.map_key()) + ": " + std::to_string(bytes.size()) + " of " +
                        std::to_string(ref.bytes()) + " bytes arrived");
  return bytes;
}

std::optional<Worker::Outcome> Worker::ObtainMap(const v1::Task& task, const std::string& ctx,
                                                 const ParsedTask& parsed, const SceneRuntime& scene) {
  const v1::MapRef& ref = task.map();
  const JobRenderSettings resolved = parsed.settings.Resolved(scene.description);
  const std::string cache_key = MapCacheKey(task.scene_hash(), resolved, parsed.spec.map_seed);
  if (ForgetFetchedMap(cache_key, ref.digest()))
    spdlog::warn("map {} for {}: the one in memory was fetched under another digest: obtained again",
                 Short(ref.map_key()), ctx);
  if (maps_->Find(cache_key)) return std::nullopt;
  // The bytes must be the map the coordinator named, and the map that of this task's seed.
  auto usable = [&](const std::string& bytes) -> std::shared_ptr<const PhotonMaps> {
    std::optional<PhotonMaps> maps = ReadNamedPhotonMaps(bytes, ref.digest(), parsed.spec.map_seed);
    return maps ? std::make_shared<const PhotonMaps>(std::move(*maps)) : nullptr;
  };
  SetState(State::kBuildingMap, ctx);
  try {
    if (std::optional<std::string> bytes = map_disk_.Get(ref.map_key())) {
      std::shared_ptr<const PhotonMaps> maps;
      try {
        maps = usable(*bytes);
      } catch (const InputError& e) {
        spdlog::warn("map {} on disk: {}: removed", Short(ref.map_key()), e.what());
      }
      if (maps) {
        maps_->Insert(cache_key, std::move(maps));
        NoteFetchedMap(cache_key, ref.digest());
        spdlog::info("map {} for {} from disk cache ({} bytes)", Short(ref.map_key()), ctx, bytes->size());
        std::lock_guard lock(mutex_);
        ++counters_.maps_from_disk;
        return std::nullopt;
      }
      map_disk_.Remove(ref.map_key());
    }
  } catch (const std::exception& e) {
    spdlog::warn("map disk cache {}: {}", map_disk_.dir().string(), e.what());
  }

  // Trace or fetch (docs/farm.md, "Photon maps traced once"): photons × measured seconds per photon against
  // bytes ÷ measured bandwidth. The same map either way (docs/design.md, G1), so only time is at stake.
  const double spp = seconds_per_photon_ > 0 ? seconds_per_photon_ : kDefaultSecondsPerPhoton;
  const double bps = bytes_per_second_ > 0 ? bytes_per_second_ : kDefaultBytesPerSecond;
  const double trace_s = double(parsed.settings.photons) * spp;
  const double fetch_s = double(ref.bytes()) / bps;
  const bool fetch = fetch_s <= trace_s;
  spdlog::info(
      "map {} for {}: {}: fetch {} bytes / {:.1f} MB/s{} = {:.3f} s vs trace {} photons x {:.3f} us{} = "
      "{:.3f} s",
      Short(ref.map_key()), ctx, fetch ? "fetch" : "trace", ref.bytes(), bps / 1e6,
      bytes_per_second_ > 0 ? " (measured)" : " (default)", fetch_s, parsed.settings.photons, spp * 1e6,
      seconds_per_photon_ > 0 ? " (measured)" : " (default)", trace_s);
  if (!fetch) return std::nullopt;

  FaultPoint("fetch", ctx);
  for (int attempt = 1; attempt <= kFetchAttempts; ++attempt) {
    const Clock::time_point t0 = Clock::now();
    try {
      const std::string bytes = FetchMapBytes(ref, ctx);
      const double seconds = SecondsSince(t0);
      std::shared_ptr<const PhotonMaps> maps = usable(bytes);
      if (!maps) throw TransferError("map " + Short(ref.map_key()) + ": digest or seed mismatch: refused");
      maps_->Insert(cache_key, std::move(maps));
      NoteFetchedMap(cache_key, ref.digest());
      if (seconds > 0) {
        const double measured = double(bytes.size()) / seconds;
        bytes_per_second_ = bytes_per_second_ > 0 ? 0.5 * (bytes_per_second_ + measured) : measured;
      }
      spdlog::info("map {} for {} fetched: {} bytes in {:.3f} s (attempt {})", Short(ref.map_key()), ctx,
                   bytes.size(), seconds, attempt);
      try {
        map_disk_.Put(ref.map_key(), bytes);
      } catch (const std::exception& e) {
        spdlog::warn("map disk cache {}: {}", map_disk_.dir().string(), e.what());
      }
      std::lock_guard lock(mutex_);
      ++counters_.maps_fetched;
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
        return Outcome::kConnectionLost;
      }
      spdlog::warn("FetchMap for {}: {}", ctx, StatusToString(e.status()));
      break;
    }
  }
  spdlog::warn("map {} for {}: not fetched: traced here instead", Short(ref.map_key()), ctx);
  return std::nullopt;
}

void Worker::NoteFetchedMap(const std::string& cache_key, const std::string& digest) {
  std::lock_guard lock(mutex_);
  fetched_maps_[cache_key] = digest;
}

bool Worker::ForgetFetchedMap(const std::string& cache_key, const std::string& digest) {
  {
    std::lock_guard lock(mutex_);
    auto it = fetched_maps_.find(cache_key);
    if (it == fetched_maps_.end()) return false;
    if (!digest.empty() && it->second == digest) return false;  // the map the task names
    fetched_maps_.erase(it);
  }
  // A map traced here since is dropped too: it costs a trace, never a wrong image.
  maps_->Erase(cache_key);
  return true;
}

}  // namespace pf::worker
