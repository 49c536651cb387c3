#include "server/scheduling/distributed_maps.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstring>
#include <fstream>

#include "common/core/atomic_file.h"
#include "common/core/error.h"
#include "common/photon/map_key.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/plan/hierarchy.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "proto/limits.h"
#include "server/jobs/random_id.h"
#include "server/scheduling/map_store_files.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

std::chrono::steady_clock::time_point Now() {
  return std::chrono::steady_clock::now();
}
double Secs(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SystemError(path.string() + ": cannot read");
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw SystemError(path.string() + ": cannot read");
  return bytes;
}

}  // namespace

std::string DistributedMapKey(const JobConfig& config, uint64_t map_seed) {
  photonfarm::v1::RenderSettings settings;
  SettingsToProto(config.settings, &settings);
  settings.mutable_photon_map()->clear_map_tracing();  // who traces it does not change the map
  // The build too: a map on disk traced by another build (before an upgrade) may hold other
  // photons, and is never reused by this one (docs/farm.md, Upgrades).
  return MapKey{config.scene_hash, settings.SerializeAsString(), map_seed}.Address(PF_VERSION);
}

DistributedMaps::DistributedMaps(DistributedMapsOptions options, const Clock& clock,
                                 SceneDirectoryOf scene_directory)
    : options_(std::move(options)), clock_(clock), scene_directory_(std::move(scene_directory)) {
  const uint64_t unit = kPhotonTracingChunk;
  options_.chunk_photons = std::max<uint64_t>(unit, (options_.chunk_photons + unit - 1) / unit * unit);
  fs::create_directories(options_.dir);
  Scan();
  builder_ = std::thread([this] { BuildLoop(); });
}

DistributedMaps::~DistributedMaps() {
  Stop();
}

void DistributedMaps::Stop() {
  {
    std::lock_guard lock(build_mu_);
    build_stop_ = true;
  }
  build_cv_.notify_all();
  if (builder_.joinable()) builder_.join();
}

void DistributedMaps::QueueBuild(const std::string& key) {
  {
    std::lock_guard lock(build_mu_);
    build_queue_.push_back(key);
  }
  build_cv_.notify_one();
}

void DistributedMaps::BuildLoop() {
  for (;;) {
    std::string key;
    {
      std::unique_lock lock(build_mu_);
      build_cv_.wait(lock, [&] { return build_stop_ || !build_queue_.empty(); });
      if (build_queue_.empty()) return;  // stopped, and every queued build done
      key = std::move(build_queue_.front());
      build_queue_.pop_front();
    }
    try {
      Build(key);  // handles its own failures (the map is left to the workers)
    } catch (const std::exception& e) {
      spdlog::error("maps: assembly of {} failed: {}", ShortKey(key), e.what());
    }
  }
}

void DistributedMaps::Scan() {
  for (const fs::directory_entry& e : fs::directory_iterator(options_.dir)) {
    const std::string name = e.path().filename().string();
    if (IsTemporaryName(name)) {
      fs::remove_all(e.path());
      continue;
    }
    if (e.is_regular_file() && name.size() == 64 + kMapFileSuffix.size() && name.ends_with(kMapFileSuffix)) {
      const std::string key = name.substr(0, 64);
      try {
        const uint64_t size = e.file_size();
        on_disk_[key] = OnDisk{BuiltMap{key, size, PhotonMapsFileDigest(e.path())}, ReadTracers(e.path())};
      } catch (const std::exception& ex) {
        spdlog::warn("maps: ignoring {}: {}", e.path().string(), ex.what());
      }
    } else if (e.is_directory() && name.ends_with(".chunks")) {
      const std::string key = name.substr(0, name.size() - 7);
      for (const fs::directory_entry& c : fs::directory_iterator(e.path())) {
        const std::string cname = c.path().filename().string();
        if (IsTemporaryName(cname)) {
          fs::remove(c.path());
          continue;
        }
        // "BEGIN-END" (photons); other names (pieces named by index before, foreign files) are
        // not pieces of any map now.
        const size_t dash = cname.find('-');
        auto number = [](std::string_view text, uint64_t* value) {
          const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), *value);
          return !text.empty() && ec == std::errc{} && ptr == text.data() + text.size();
        };
        uint64_t begin = 0, end = 0;
        if (dash != std::string::npos && number(std::string_view(cname).substr(0, dash), &begin) &&
            number(std::string_view(cname).substr(dash + 1), &end) && end > begin) {
          const std::set<std::string> tracers = ReadTracers(c.path());
          chunks_on_disk_[key][{begin, end}] = tracers.empty() ? "" : *tracers.begin();
        }
      }
    }
  }
  if (!on_disk_.empty() || !chunks_on_disk_.empty())
    spdlog::info("maps: {} built maps and traced pieces of {} maps found in {}", on_disk_.size(),
                 chunks_on_disk_.size(), options_.dir.string());
}

fs::path DistributedMaps::ChunkFile(const std::string& key, uint64_t begin, uint64_t end) const {
  return options_.dir / (key + ".chunks") / (std::to_string(begin) + "-" + std::to_string(end));
}

bool MayDistributeMaps(const JobConfig& config) {
  const JobRenderSettings& s = config.settings;
  // An importance-driven map (§4.7) depends on the camera's importons, which a piece's tracer does
  // not build: such maps are traced where they are used (distributed + importance is rejected
  // at submission, proto/convert.cpp).
  return s.integrator == IntegratorKind::kPhotonMap && s.map_tracing != MapTracingMode::kLocal &&
         s.importance == ImportanceMode::kOff && CanSerialize(s.structure) && s.photons != 0;
}

uint64_t PlanMapCount(const PlanSpec& plan) {
  switch (plan.kind) {
    case PlanKind::kMultipleMaps:
    case PlanKind::kProgressive:
      return plan.maps;
    case PlanKind::kMapsInTurn:
      return plan.samples_per_pixel;
    case PlanKind::kSkipping:
      return uint64_t(plan.rounds) * plan.stride * plan.stride;
    case PlanKind::kHierarchical:
      return MakeHierarchySchedule(plan).nmax;  // every level's maps; localization reuses level 0's
  }
  return 0;
}

const std::string* DistributedMaps::KeyFor(const Job& job, uint64_t map_index) {
  const JobConfig& config = job.config();
  const JobRenderSettings& s = config.settings;
  if (!MayDistributeMaps(config)) return nullptr;
  const auto id = std::make_pair(job.id(), map_index);
  if (auto it = keys_.find(id); it != keys_.end()) return &it->second;
  if (s.map_tracing == MapTracingMode::kAuto) {
    // Only maps that more than one render task uses: then building once saves work. Counted once
    // per job (O(tasks)); only the shared maps are remembered.
    auto [shared, first] = shared_maps_.try_emplace(job.id());
    if (first) {
      std::unordered_map<uint64_t, uint32_t> users;
      for (const TaskSpec& t : job.tasks())
        if (++users[t.map_index] == 2) shared->second.insert(t.map_index);
    }
    if (!shared->second.count(map_index)) return nullptr;
  }
  auto [it, inserted] = keys_.emplace(id, DistributedMapKey(config, MapSeed(config.seed, map_index)));
  spdlog::info("job {} map {}: traced once, distributed ({}): key {}", job.id(), map_index,
               s.map_tracing == MapTracingMode::kAuto ? "auto: several render tasks use it" : "job setting",
               ShortKey(it->second));
  return &it->second;
}

DistributedMaps::Map& DistributedMaps::MapOf(const Job& job, uint64_t map_index, const std::string& key,
                                             MapUpdate& update) {
  auto it = maps_.find(key);
  if (it != maps_.end()) return it->second;
  Map& m = maps_[key];
  m.key = key;
  m.seq = next_seq_++;
  m.job_id = job.id();
  m.map_index = map_index;
  m.map_seed = MapSeed(job.config().seed, map_index);
  m.config = job.shared_config();
  m.photons = job.config().settings.photons;
  m.chunk_photons = options_.chunk_photons;
  if (auto built = on_disk_.find(key); built != on_disk_.end()) {
    SetStateLocked(m, Map::State::kBuilt);
    m.built = built->second.built;
    m.contributors = built->second.contributors;
    TouchLocked(key);  // a use (the quota's order)
    spdlog::info("job {} map {}: built map {} found on disk ({} bytes)", job.id(), map_index, ShortKey(key),
                 m.built.bytes);
    return m;
  }
  m.chunks.resize((m.photons + m.chunk_photons - 1) / m.chunk_photons);
  if (auto found = chunks_on_disk_.find(key); found != chunks_on_disk_.end())
    for (const auto& [range, uploader] : found->second) {
      const auto [begin, end] = range;
      const uint64_t c = begin / m.chunk_photons;
      if (begin % m.chunk_photons == 0 && c < m.chunks.size() &&
          end == std::min(m.photons, begin + m.chunk_photons) && m.chunks[c].state != Chunk::State::kDone) {
        PieceTransitions().Move(m.chunks[c].state, Chunk::State::kDone);
        m.chunks[c].uploader = uploader;
        ++m.done;
      }
    }
  spdlog::info("job {} map {}: {} photons in {} pieces of {} ({} already traced on disk)", job.id(),
               map_index, m.photons, m.chunks.size(), m.chunk_photons, m.done);
  if (m.done == m.chunks.size()) {
    SetStateLocked(m, Map::State::kBuilding);
    QueueBuild(key);
  } else {
    update.maps.insert(key);  // its pieces join the Scheduler's queue
  }
  return m;
}

bool DistributedMaps::RenderTaskReady(const Job& job, const TaskSpec& task, MapUpdate& update) {
  std::lock_guard lock(mu_);
  const std::string* key = KeyFor(job, task.map_index);
  if (!key) return true;
  Map& m = MapOf(job, task.map_index, *key, update);
  if (m.state == Map::State::kBuilt || m.state == Map::State::kLeftToWorkers) return true;
  m.waiting.insert({job.id(), task.map_index});
  return false;
}

void DistributedMaps::SetStateLocked(Map& m, Map::State state) {
  MapTransitions().Move(m.state, state);
}

MapTracingHook::QueuedPieces DistributedMaps::QueuedPiecesOf(const std::string& map_key) {
  std::lock_guard lock(mu_);
  QueuedPieces queued;
  auto it = maps_.find(map_key);
  if (it == maps_.end()) return queued;
  const Map& m = it->second;
  queued.map_seq = m.seq;
  if (m.state != Map::State::kTracing) return queued;
  for (uint32_t c = 0; c < m.chunks.size(); ++c)
    if (m.chunks[c].state == Chunk::State::kQueued) queued.pieces.push_back(c);
  return queued;
}

std::optional<Lease> DistributedMaps::LeasePiece(const TaskQueue::Piece& piece, const std::string& worker_id,
                                                 const IssuePieceLease& issue) {
  std::lock_guard lock(mu_);
  auto it = maps_.find(piece.map_key);
  if (it == maps_.end() || it->second.state != Map::State::kTracing ||
      piece.index >= it->second.chunks.size() ||
      it->second.chunks[piece.index].state != Chunk::State::kQueued)
    return std::nullopt;
  Map& m = it->second;
  const uint32_t pick = piece.index;
  Chunk& chunk = m.chunks[pick];
  // The id first: if issuing throws, the piece is still queued, not leased with no lease behind it.
  std::string lease_id = issue(m.job_id, m.key, pick, chunk.attempts + 1);
  PieceTransitions().Move(chunk.state, Chunk::State::kLeased);
  ++chunk.attempts;
  chunk.lease_id = std::move(lease_id);
  chunk.worker_id = worker_id;
  ++counters_.chunks_leased;
  Lease lease;
  lease.lease_id = chunk.lease_id;
  lease.job_id = m.job_id;
  lease.task_id = pick;
  lease.attempt = chunk.attempts;
  lease.task.map_index = m.map_index;
  lease.task.map_seed = m.map_seed;
  lease.config = m.config;
  TraceChunkLease c;
  c.map_key = m.key;
  c.photon_begin = uint64_t(pick) * m.chunk_photons;
  c.photon_end = std::min(m.photons, c.photon_begin + m.chunk_photons);
  c.chunk_index = pick;
  c.chunk_count = uint32_t(m.chunks.size());
  lease.chunk = c;
  spdlog::info("job {} map {} piece {}/{}: leased to {} (photons [{}, {}), attempt {}, map {})", m.job_id,
               m.map_index, pick, m.chunks.size(), limits::Quote(worker_id, limits::kMaxWorkerIdBytes),
               c.photon_begin, c.photon_end, chunk.attempts, ShortKey(m.key));
  return lease;
}

std::optional<BuiltMap> DistributedMaps::MapFor(const std::string& job_id, uint64_t map_index) {
  std::lock_guard lock(mu_);
  auto k = keys_.find({job_id, map_index});
  if (k == keys_.end()) return std::nullopt;
  auto it = maps_.find(k->second);
  if (it == maps_.end() || it->second.state != Map::State::kBuilt) return std::nullopt;
  return it->second.built;
}

std::optional<fs::path> DistributedMaps::MapFile(const std::string& key) {
  std::lock_guard lock(mu_);
  auto it = maps_.find(key);
  if ((it != maps_.end() && it->second.state == Map::State::kBuilt) || on_disk_.count(key)) {
    TouchLocked(key);  // served: a use (the quota's order)
    return MapFileOf(options_.dir, key);
  }
  return std::nullopt;
}

DistributedMaps::UploadAdmission DistributedMaps::BeginUpload(const std::string& lease_id,
                                                              const std::string& worker_id) {
  if (!scheduler_) return UploadAdmission::kNotLive;
  // The lease through the Scheduler's one lease path: live, and this worker's (else refused there).
  const Scheduler::PieceLeaseRef ref = scheduler_->PieceLeaseOf(lease_id, worker_id, "UploadMapPiece");
  if (ref.status == Scheduler::PieceLeaseRef::Status::kNotHolder) return UploadAdmission::kNotHolder;
  if (ref.status != Scheduler::PieceLeaseRef::Status::kLive) return UploadAdmission::kNotLive;
  std::lock_guard lock(mu_);
  auto it = maps_.find(ref.map_key);
  if (it == maps_.end() || it->second.state != Map::State::kTracing ||
      it->second.chunks[ref.piece].state == Chunk::State::kDone)
    return UploadAdmission::kNotLive;
  if (!uploading_.insert(lease_id).second) return UploadAdmission::kBusy;
  return UploadAdmission::kAdmitted;
}

void DistributedMaps::EndUpload(const std::string& lease_id) {
  std::lock_guard lock(mu_);
  uploading_.erase(lease_id);
}

DistributedMaps::Accepted DistributedMaps::AcceptChunk(const std::string& lease_id,
                                                       const std::string& worker_id,
                                                       const std::string& bytes) {
  std::string key;
  uint32_t index = 0;
  uint64_t begin = 0, end = 0, map_seed = 0;
  bool light_ids = false, origins = false;
  std::shared_ptr<const JobConfig> config;
  if (!scheduler_) return Accepted::kLate;
  // The lease through the Scheduler's one lease path: live, and this worker's (else refused there).
  const Scheduler::PieceLeaseRef ref = scheduler_->PieceLeaseOf(lease_id, worker_id, "UploadMapPiece");
  if (ref.status == Scheduler::PieceLeaseRef::Status::kNotHolder) return Accepted::kNotHolder;
  if (ref.status != Scheduler::PieceLeaseRef::Status::kLive) return Accepted::kLate;
  {
    std::lock_guard lock(mu_);
    key = ref.map_key;
    index = ref.piece;
    const Map& m = maps_.at(key);
    if (m.state != Map::State::kTracing || m.chunks[index].state == Chunk::State::kDone)
      return Accepted::kLate;
    begin = uint64_t(index) * m.chunk_photons;
    end = std::min(m.photons, begin + m.chunk_photons);
    const JobRenderSettings& s = m.config->settings;
    light_ids = s.direct && *s.direct == DirectLightMode::kPhotonDirect;
    origins = s.occlusion_test;
    config = m.config;
    map_seed = m.map_seed;
  }
  // Parsed and written outside the lock (O(photons) and I/O).
  const PhotonChunk chunk = DeserializePhotonChunk(bytes);
  if (chunk.begin != begin || chunk.end != end)
    throw InputError("photons [" + std::to_string(chunk.begin) + ", " + std::to_string(chunk.end) +
                     ") uploaded for the piece of photons [" + std::to_string(begin) + ", " +
                     std::to_string(end) + ")");
  if ((light_ids && !chunk.light_ids) || (origins && !chunk.origins))
    throw InputError("the piece lacks the light ids or origins the job's estimators need");
  const auto t_check = Now();
  // Chosen when the piece arrives, by the CSPRNG: the uploader cannot know which pieces are traced
  // again in full.
  const bool in_full = options_.verify_fraction >= 1 ||
                       (options_.verify_fraction > 0 && RandomUnit() < options_.verify_fraction);
  if (const std::string wrong = MismatchOf(*config, map_seed, chunk, bytes, in_full); !wrong.empty()) {
    RefuseAndConvict(key, index, lease_id, worker_id, wrong);
    throw InputError(wrong);
  }
  const double check_seconds = Secs(t_check, Now());
  const fs::path file = ChunkFile(key, begin, end);
  fs::create_directories(file.parent_path());
  WriteTracers(file, {worker_id});  // before the piece: a stored piece always says who traced it
  WriteFileAtomically(file, bytes);
  bool build = false;
  std::string job_id;
  uint64_t map_index = 0;
  size_t done = 0, total = 0;
  {
    std::lock_guard lock(mu_);
    Map& m = maps_.at(key);
    Chunk& c = m.chunks[index];
    if (m.state != Map::State::kTracing || c.state == Chunk::State::kDone) return Accepted::kLate;
    // Its lease (or, re-leased meanwhile, another worker's) ends here: the Scheduler's entry is
    // found no longer current on its next use (PieceLeaseCurrent).
    c.lease_id.clear();
    PieceTransitions().Move(c.state, Chunk::State::kDone);
    c.uploader = worker_id;
    ++m.done;
    ++counters_.chunks_stored;
    counters_.chunks_verified_in_full += in_full;
    done = m.done;
    total = m.chunks.size();
    job_id = m.job_id;
    map_index = m.map_index;
    if (m.done == m.chunks.size()) {
      SetStateLocked(m, Map::State::kBuilding);
      build = true;
    }
  }
  spdlog::info("job {} map {} piece {}: stored ({} bytes, {} checked in {:.3f} s, {}/{} pieces in)", job_id,
               map_index, index, bytes.size(), in_full ? "every photon" : "first photons", check_seconds,
               done, total);
  if (build) {
    ReleaseCheckSceneIfUnused();
    QueueBuild(key);
  }
  return Accepted::kStored;
}

std::set<std::string> DistributedMaps::ReadTracers(const fs::path& file) {
  std::set<std::string> workers;
  std::ifstream in(TracersFile(file));
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) workers.insert(line);
  return workers;
}

void DistributedMaps::WriteTracers(const fs::path& file, const std::set<std::string>& workers) {
  std::string text;
  for (const std::string& w : workers) text += w + "\n";
  WriteFileAtomically(TracersFile(file), text);
}

void DistributedMaps::Build(const std::string& key) {
  std::shared_ptr<const JobConfig> config;
  uint64_t map_seed = 0, map_index = 0, photons = 0, chunk_photons = 1;
  size_t count = 0;
  std::string job_id;
  uint64_t generation = 0;
  std::set<std::string> tracers;
  {
    std::lock_guard lock(mu_);
    const Map& m = maps_.at(key);
    generation = m.generation;
    for (const Chunk& c : m.chunks)
      if (!c.uploader.empty()) tracers.insert(c.uploader);
    config = m.config;
    map_seed = m.map_seed;
    map_index = m.map_index;
    count = m.chunks.size();
    job_id = m.job_id;
    photons = m.photons;
    chunk_photons = m.chunk_photons;
  }
  auto file_of = [&](uint32_t c) {
    const uint64_t begin = uint64_t(c) * chunk_photons;
    return ChunkFile(key, begin, std::min(photons, begin + chunk_photons));
  };
  MapUpdate update;  // for the Scheduler: pieces queued again, or the map's render tasks released
  const auto t0 = std::chrono::steady_clock::now();
  try {
    std::vector<PhotonChunk> pieces;
    pieces.reserve(count);
    for (uint32_t c = 0; c < count; ++c) {
      try {
        pieces.push_back(DeserializePhotonChunk(ReadFile(file_of(c))));
      } catch (const std::exception& e) {
        // A piece damaged or gone on disk (InputError, SystemError): trace it again.
        std::lock_guard lock(mu_);
        Map& m = maps_.at(key);
        if (m.generation != generation) return;  // purged meanwhile (WorkerConvicted): traced again
        RemoveWithTracers(file_of(c));
        // Building → tracing once (further unreadable pieces find it tracing).
        if (m.state != Map::State::kTracing) SetStateLocked(m, Map::State::kTracing);
        PieceTransitions().Check(m.chunks[c].state, Chunk::State::kQueued);
        m.chunks[c] = Chunk{};
        --m.done;
        update.maps.insert(key);
        spdlog::warn("job {} map {} piece {}: stored piece unreadable ({}): traced again", job_id, map_index,
                     c, e.what());
      }
    }
    if (pieces.size() != count) {
      if (scheduler_) scheduler_->ApplyMapUpdate(update);
      return;
    }
    const auto t_read = std::chrono::steady_clock::now();
    const SceneDescription scene = LoadBundle(scene_directory_(config->scene_hash), config->scene_entry);
    PhotonMapsOptions mo = config->settings.Resolved(scene).MapsOptions();
    mo.tracing.map_seed = map_seed;
    mo.tracing.threads = options_.build_threads;
    const PhotonMaps maps = AssemblePhotonMaps(pieces, mo);
    std::vector<PhotonChunk>().swap(pieces);
    const auto t_assembled = std::chrono::steady_clock::now();
    const std::string bytes = SerializePhotonMaps(maps);
    const auto t_serialized = std::chrono::steady_clock::now();
    const fs::path file = MapFileOf(options_.dir, key);
    WriteTracers(file, tracers);  // before the map: a stored map always says who traced its pieces
    WriteFileAtomically(file, bytes);
    const BuiltMap built{key, bytes.size(), PhotonMapsDigest(bytes)};
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    spdlog::info(
        "job {} map {}: built once from {} pieces: {} global + {} caustic + {} direct photons, {} bytes, "
        "read {:.3f} s, assemble {:.3f} s (balance {:.3f} s), serialize {:.3f} s, write {:.3f} s: {:.3f} s "
        "(map {})",
        job_id, map_index, count, maps.global->size(), maps.caustic ? maps.caustic->size() : 0,
        maps.direct ? maps.direct->size() : 0, bytes.size(), Secs(t0, t_read), Secs(t_read, t_assembled),
        maps.stats.build_seconds, Secs(t_assembled, t_serialized), Secs(t_serialized, Now()), seconds,
        ShortKey(key));
    {
      std::lock_guard lock(mu_);
      Map& m = maps_.at(key);
      if (m.generation != generation) {
        // A conviction purged it while it was assembled: it holds pieces of the convicted worker.
        RemoveWithTracers(file);
        spdlog::warn("job {} map {}: assembled from pieces of a convicted worker: dropped", job_id,
                     map_index);
        return;
      }
      SetStateLocked(m, Map::State::kBuilt);
      m.built = built;
      m.contributors = tracers;
      update.release.assign(m.waiting.begin(), m.waiting.end());
      m.waiting.clear();
      ++counters_.maps_built;
      // Under the lock: a conviction may trace the map again right after, into the same folder.
      std::error_code ec;
      fs::remove_all(options_.dir / (key + ".chunks"), ec);
    }
  } catch (const std::exception& e) {
    std::lock_guard lock(mu_);
    if (maps_.at(key).generation == generation)
      LeaveToWorkersLocked(maps_.at(key), std::string("assembly failed: ") + e.what(), update);
  }
  if (scheduler_) scheduler_->ApplyMapUpdate(update);
  EnforceQuotaNow();  // a map stored: the quota (this map is live: its jobs wait for it)
}

void DistributedMaps::LeaveToWorkersLocked(Map& m, const std::string& why, MapUpdate& update) {
  spdlog::warn("job {} map {}: left to the workers (each traces it): {}", m.job_id, m.map_index, why);
  SetStateLocked(m, Map::State::kLeftToWorkers);  // its piece leases are no longer current
  update.maps.insert(m.key);                      // its queued pieces leave the Scheduler's queue
  update.release.insert(update.release.end(), m.waiting.begin(), m.waiting.end());
  m.waiting.clear();
  ++counters_.maps_left_to_workers;
}

void DistributedMaps::RequeueLocked(Map& m, uint32_t index, const std::string& kind, const std::string& why,
                                    MapUpdate& update) {
  Chunk& c = m.chunks[index];
  spdlog::warn("job {} map {} piece {}: attempt {} ended: {}", m.job_id, m.map_index, index, c.attempts, why);
  update.failures.push_back(PieceFailure{m.job_id, c.worker_id, kind, why, index, c.attempts});
  if (c.worker_id.empty())
    ++c.unattributed_failures;
  else if (std::find(c.failed_workers.begin(), c.failed_workers.end(), c.worker_id) == c.failed_workers.end())
    c.failed_workers.push_back(c.worker_id);
  PieceTransitions().Move(c.state, Chunk::State::kQueued);
  c.lease_id.clear();
  update.maps.insert(m.key);
  // Failures on max_attempts distinct workers, as for a task (scheduler.h): one bad worker is
  // blocklisted for the job before it can use the piece up.
  const uint32_t distinct = uint32_t(c.failed_workers.size()) + c.unattributed_failures;
  if (distinct >= options_.max_attempts)
    LeaveToWorkersLocked(m,
                         "piece " + std::to_string(index) + " failed " + std::to_string(c.attempts) +
                             " times, on " + std::to_string(distinct) + " workers",
                         update);
}

bool DistributedMaps::PieceLeaseCurrent(const std::string& map_key, uint32_t piece,
                                        const std::string& lease_id) {
  std::lock_guard lock(mu_);
  auto it = maps_.find(map_key);
  if (it == maps_.end() || it->second.state != Map::State::kTracing || piece >= it->second.chunks.size())
    return false;
  const Chunk& c = it->second.chunks[piece];
  return c.state == Chunk::State::kLeased && c.lease_id == lease_id;
}

std::vector<std::string> DistributedMaps::JobsOfMap(const std::string& map_key) {
  std::lock_guard lock(mu_);
  auto it = maps_.find(map_key);
  return it == maps_.end() ? std::vector<std::string>{} : JobsOfLocked(it->second);
}

MapUpdate DistributedMaps::PieceReturned(const std::string& map_key, uint32_t piece,
                                         const std::string& lease_id) {
  std::lock_guard lock(mu_);
  MapUpdate update;
  auto it = maps_.find(map_key);
  if (it == maps_.end() || it->second.state != Map::State::kTracing) return update;
  Map& m = it->second;
  Chunk& c = m.chunks[piece];
  if (c.state != Chunk::State::kLeased || c.lease_id != lease_id) return update;
  PieceTransitions().Move(c.state, Chunk::State::kQueued);
  c.lease_id.clear();
  --c.attempts;
  ++counters_.chunks_returned;
  update.maps.insert(map_key);
  spdlog::info("job {} map {} piece {}: lease {} never reached the worker: queued again", m.job_id,
               m.map_index, piece, lease_id);
  return update;
}

MapUpdate DistributedMaps::PieceLeaseEnded(const PieceLeaseEnd& end) {
  std::lock_guard lock(mu_);
  MapUpdate update;
  auto it = maps_.find(end.map_key);
  if (it == maps_.end() || it->second.state != Map::State::kTracing) return update;
  Map& m = it->second;
  const Chunk& c = m.chunks[end.piece];
  if (c.state != Chunk::State::kLeased || c.lease_id != end.lease_id) return update;
  if (end.why == PieceLeaseEnd::Why::kExpired) {
    ++counters_.chunks_expired;
    RequeueLocked(m, end.piece, "piece-expired", "lease expired (worker " + end.worker_id + ")", update);
  } else {
    RequeueLocked(m, end.piece, "piece-failed", "failed by " + end.worker_id + ": " + end.reason, update);
  }
  return update;
}

DistributedMaps::Removed DistributedMaps::RemoveMapsOf(
    const std::string& job_id, const JobConfig& deleted,
    const std::vector<std::shared_ptr<const JobConfig>>& remaining) {
  Removed out;
  std::vector<std::string> candidates;
  if (MayDistributeMaps(deleted)) {
    // Keys are hashes (outside the locks): a remaining job shares the deleted one's maps only with
    // its scene, settings and seed, i.e. the same key for map 0.
    const std::string first = DistributedMapKey(deleted, MapSeed(deleted.seed, 0));
    uint64_t used_below = 0;
    for (const std::shared_ptr<const JobConfig>& other : remaining)
      if (other->seed == deleted.seed && MayDistributeMaps(*other) &&
          DistributedMapKey(*other, MapSeed(other->seed, 0)) == first)
        used_below = std::max(used_below, PlanMapCount(other->plan));
    for (uint64_t i = used_below; i < PlanMapCount(deleted.plan); ++i)
      candidates.push_back(DistributedMapKey(deleted, MapSeed(deleted.seed, i)));
  }
  std::lock_guard lock(mu_);
  for (auto it = keys_.lower_bound({job_id, 0}); it != keys_.end() && it->first.first == job_id;)
    it = keys_.erase(it);
  shared_maps_.erase(job_id);
  std::set<std::string> protected_keys;  // of jobs registered since `remaining` was taken
  for (const auto& [id, key] : keys_) protected_keys.insert(key);
  for (const std::string& key : candidates) {
    if (protected_keys.count(key)) continue;
    if (auto m = maps_.find(key); m != maps_.end()) {
      if (m->second.state == Map::State::kTracing || m->second.state == Map::State::kBuilding ||
          !m->second.waiting.empty())
        continue;
      maps_.erase(m);
    }
    on_disk_.erase(key);
    chunks_on_disk_.erase(key);
    uint64_t bytes = 0;
    bool found = false;
    std::error_code ec;
    const fs::path file = MapFileOf(options_.dir, key);
    for (const fs::path& f : {file, TracersFile(file)}) {
      const uintmax_t size = fs::file_size(f, ec);
      if (!ec && fs::remove(f, ec)) {
        bytes += size;
        found = found || f == file;
      }
    }
    const fs::path chunks = options_.dir / (key + ".chunks");
    if (fs::is_directory(chunks, ec)) {
      for (fs::recursive_directory_iterator c(chunks, ec), end; !ec && c != end; c.increment(ec))
        if (std::error_code fec; c->is_regular_file(fec)) bytes += c->file_size(fec);
      fs::remove_all(chunks, ec);
      found = true;
    }
    if (!found) continue;
    ++out.maps;
    out.bytes += bytes;
    spdlog::info("job {}: map {} removed with the job ({} bytes)", job_id, ShortKey(key), bytes);
  }
  return out;
}

DistributedMaps::Counters DistributedMaps::counters() const {
  std::lock_guard lock(mu_);
  return counters_;
}

}  // namespace pf::server
