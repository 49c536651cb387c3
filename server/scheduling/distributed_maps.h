#pragma once
// Photon maps traced once (docs/farm.md "Photon maps traced once"): the coordinator's
// side of distributed photon tracing.
//
//   job submitted ──▶ map pieces queued in the Scheduler's TaskQueue (TraceChunk tasks, served
//                     before render tasks)
//   worker traces photons [b, e) ──UploadPhotonChunk──▶ piece checked, written to disk
//   all pieces in ──▶ assembled and balanced once, here, on a thread of its own (never under
//                     the scheduler's lock) ──▶ <data-dir>/maps/<key>.pfmaps
//   ──▶ released (MapUpdate::release): the render tasks of that map join the queue; their Task.map says
//       where to fetch it (FetchMap) — or the worker traces it itself if that is faster.
//
// Which maps: MapTracingMode::kDistributed — every map of the job (kd-tree only, checked at
// submission); kAuto — kd-tree photon maps that more than one of the job's render tasks uses
// (a map used once gains nothing from travelling: its only user could trace it as fast).
//
// Key: hex SHA-256 of "photonfarm-map-v1", the coordinator's build (PF_VERSION: a map traced by
// another build before an upgrade is never reused), the scene hash, the job's render settings
// (proto, map_tracing cleared) and the map seed: the settings with the scene decide every `auto`,
// so the key names one map; jobs with the same scene, settings and seed share it. It is the
// Address of the map's MapKey (common/photon/map_key.h), the key type of every map cache.
//
// Not a scheduler of its own: the component the Scheduler calls for what is map-specific. The
// Scheduler owns the queue of pieces as of render tasks — one TaskQueue (task_queue.h) whose items
// are render tasks or pieces (a map's key and a piece index; pieces first, oldest map first, lowest
// piece first, a map passed over for a worker blocklisted in one of its jobs) — and their leases:
// one LeaseTable (lease_table.h) whose entries say their kind (render task | map piece) and what
// they name, one issuer and one form of id (the job, the piece, the attempt and 128 bits from the
// CSPRNG: it cannot be guessed, and a restarted coordinator never hands out an id again), one path
// for ExtendLease, FailTask, ReturnLease and the upload (Scheduler::FindLiveLease, dispatching by
// the entry's kind, never by the id's form) and one expiry tick (Scheduler::Tick). A lease is bound
// to the worker it was leased to: ExtendLease, the upload and FailTask of another worker change
// nothing (kNotHolder; docs/security.md, "Leases are bound to their worker"); the presenter is
// blocklisted in every job of the map. Here: each piece's state — moved only as PieceTransitions
// allows (map_states.h) — attempts and failed workers, the piece and map files, the checks and the
// assembly; no queue and no choice of the next piece. The Scheduler leases the piece its queue
// chose (LeasePiece) and tells what became of a lease (PieceReturned, PieceLeaseEnded); each answer
// is a MapUpdate (map_tracing_hook.h) — the maps whose queued pieces changed (the Scheduler sets
// them in its queue from QueuedPiecesOf), failed attempts to count against their workers, maps to
// release — that the Scheduler applies in the same hold of its lock. Events that begin here (an
// upload refused, an assembly done or failed, a stored piece unreadable, a conviction) hand their
// update to Scheduler::ApplyMapUpdate. A piece that moves on without the Scheduler (stored, its map
// left to the workers or purged) leaves a lease entry that is no longer current
// (PieceLeaseCurrent): the Scheduler drops it on its next use or at its deadline.
//
// Map builds are not a kind of the queue: the queue holds work leased to workers, with leases,
// attempts and blocklists, and an assembly is the coordinator's own — one at a time on its builder
// thread, from the pieces on its disk — so it is a checked map state (kBuilding, map_states.h) with
// the builder's FIFO (docs/design.md, "One queue").
//
// Locks: the Scheduler's lock, then mu_ (RenderTaskReady, QueuedPiecesOf, LeasePiece,
// PieceLeaseCurrent, JobsOfMap, PieceReturned, PieceLeaseEnded are called under the Scheduler's
// lock and take mu_ briefly, and never call the Scheduler); this class calls the Scheduler
// (PieceLeaseOf, ConvictWorker, ApplyMapUpdate) only without mu_. Checking a piece and assembling a
// map hold neither lock.
//
// Pieces checked: besides its photon range and attributes, an upload's first kPhotonTracingChunk
// photons are traced here and must equal the upload's, bit for bit (photon i depends on the map
// seed and i alone, and a trace of [b, b + 4096) is the first part of each list of a trace of
// [b, e)): an empty, truncated or foreign piece is refused (InputError), however well-formed. One
// scene is kept loaded for it while maps of that scene trace. It does not prove the rest of the
// piece: a worker holding the lease could still upload wrong photons after the first 4096 — so a
// fraction of the pieces (`verify_fraction`, chosen by the CSPRNG when the piece arrives) is traced
// here in full and must equal the upload byte for byte.
//
// Verification (docs/farm.md "Result verification"): a piece that is not the coordinator's trace
// is refused, and with `convict` its uploader is convicted (Scheduler::ConvictWorker for the map's
// job). Every piece and built map records who traced it (a file beside it, `.by`: one worker id a
// line), so that a conviction deletes every stored map holding a piece of the convicted worker —
// built or still tracing, in memory or found on disk — and traces it again without it
// (WorkerConvicted); the jobs whose render tasks used such a built map are restarted by the
// scheduler. A map traced again has another digest than the poisoned one (MapRef.digest), so no
// worker's cache serves the old one (worker/map_obtainer.cpp checks it).
//
// Failures: a piece whose lease runs out or whose worker fails it is queued again (attempt + 1),
// and the failure counts against the worker in the map's job (MapUpdate::failures:
// blocklist, quarantine; a blocklisted worker is leased no pieces of that job). After failures on
// max_attempts distinct workers, or if assembling fails, the map is left to the workers (its
// render tasks are released without a built map and each worker traces it, as with kLocal) —
// never stuck. Durability: pieces and built maps are files under `dir`; a restarted coordinator
// finds them (Scan at start-up) and queues only the missing pieces. Leases are not durable (as for
// render tasks). Nothing here touches samples: render results are merged by the Scheduler alone.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "common/photon/photon_chunk.h"
#include "common/render/scene_runtime.h"
#include "server/clock.h"
#include "server/jobs/job.h"
#include "server/scheduling/map_states.h"
#include "server/scheduling/map_tracing_hook.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

struct DistributedMapsOptions {
  std::filesystem::path dir;       // <data-dir>/maps
  uint32_t max_attempts = 3;       // (a piece's lease lasts the Scheduler's lease_seconds)
  int build_threads = 1;           // threads of one assembly (the kd-tree balance), 0 = all cores
  uint64_t chunk_photons = 65536;  // photons per piece, rounded up to a multiple of 4096
  // Result verification (see the header comment): the fraction of uploaded pieces traced again in
  // full, and whether a piece proven wrong convicts its uploader (off when builds are mixed: two
  // builds may trace other photons).
  double verify_fraction = 0;
  bool convict = false;
  // The store's quota in bytes (pf-coordinator --maps-quota; map_quota.h), 0 = none.
  uint64_t quota_bytes = 0;
};

struct BuiltMap {
  std::string key;
  uint64_t bytes = 0;
  std::string digest;  // hex SHA-256 of the byte form's content (its trailer)
};

// The directory of a stored scene bundle by its hash (SceneStore::DirectoryOf): passed in, so that
// scheduling does not depend on the store (docs/design.md, layers).
using SceneDirectoryOf = std::function<std::filesystem::path(const std::string& scene_hash)>;

class DistributedMaps final : public MapTracingHook {
 public:
  DistributedMaps(DistributedMapsOptions options, const Clock& clock, SceneDirectoryOf scene_directory);
  ~DistributedMaps() override;
  DistributedMaps(const DistributedMaps&) = delete;
  DistributedMaps& operator=(const DistributedMaps&) = delete;

  // Set once, before jobs are added.
  void SetScheduler(Scheduler* scheduler) { scheduler_ = scheduler; }

  // MapTracingHook, under the scheduler's lock (map_tracing_hook.h).
  bool RenderTaskReady(const Job& job, const TaskSpec& task, MapUpdate& update) override;
  QueuedPieces QueuedPiecesOf(const std::string& map_key) override;
  std::optional<Lease> LeasePiece(const TaskQueue::Piece& piece, const std::string& worker_id,
                                  const IssuePieceLease& issue) override;
  bool PieceLeaseCurrent(const std::string& map_key, uint32_t piece, const std::string& lease_id) override;
  std::vector<std::string> JobsOfMap(const std::string& map_key) override;
  // A piece lease that never reached its worker (the long poll was cancelled): queued again at
  // once, its attempt not counted, instead of idling until the lease runs out.
  MapUpdate PieceReturned(const std::string& map_key, uint32_t piece, const std::string& lease_id) override;
  // A piece's lease failed or ran out (see the header comment, "Failures").
  MapUpdate PieceLeaseEnded(const PieceLeaseEnd& end) override;

  // The built map a render task of `job_id` with this map index should fetch; nullopt if its
  // workers trace it (not distributed, or left to them).
  std::optional<BuiltMap> MapFor(const std::string& job_id, uint64_t map_index);
  // The file of a built map, nullopt if there is none with that key.
  std::optional<std::filesystem::path> MapFile(const std::string& key);

  // An upload's admission, checked on its first part before anything is buffered: only a live
  // piece lease (Scheduler::PieceLeaseOf) may upload, one stream at a time. So the coordinator buffers at
  // most one piece per live piece lease (each ≤ kMaxPhotonChunkBytes), whatever a client declares or how many
  // streams it opens. EndUpload(lease) once an admitted stream is over. kNotHolder: the lease is live but
  // `worker_id` is not the worker it was leased to.
  enum class UploadAdmission { kAdmitted, kNotLive, kBusy, kNotHolder };
  UploadAdmission BeginUpload(const std::string& lease_id, const std::string& worker_id);
  void EndUpload(const std::string& lease_id);

  enum class Accepted { kStored, kLate, kNotHolder };
  // A piece's bytes (checksums already verified by the RPC) from `worker_id`: parsed, checked
  // against its lease's range, written to disk. InputError for a malformed piece (nothing stored).
  // kLate: the lease is unknown or the piece is already in; kNotHolder: another worker's lease
  // (nothing stored). May start the map's assembly.
  Accepted AcceptChunk(const std::string& lease_id, const std::string& worker_id, const std::string& bytes);
  // A convicted worker (MapTracingHook, outside the scheduler's locks): see the header comment.
  std::vector<std::string> WorkerConvicted(const std::string& worker_id) override;

  // A deleted job (docs/farm.md "Deleting jobs"), already gone from the Scheduler: its maps that no
  // job in `remaining` uses — built, left to the workers or found on disk, with their pieces and
  // `.by` records — are removed from memory and from `dir`. A map is used by a remaining job of the
  // same scene, render settings and seed whose plan reaches its index (PlanMapCount; the key of a
  // job registered since is protected too); a map still tracing or building is kept (its pieces
  // may be leased). Returns the maps removed and their bytes.
  struct Removed {
    uint32_t maps = 0;
    uint64_t bytes = 0;
  };
  Removed RemoveMapsOf(const std::string& job_id, const JobConfig& deleted,
                       const std::vector<std::shared_ptr<const JobConfig>>& remaining);

  // The quota (map_quota.h, docs/farm.md "The map store's quota"): when the store holds more than
  // options.quota_bytes, the least recently used maps go — never one a queued, running or paused
  // job of `jobs` may use (every map index its plan reaches, as RemoveMapsOf reasons), one of a job
  // registered since `jobs` was taken, or one still tracing or building. Each eviction is logged; a
  // quota only live maps keep exceeded is warned about once (until it is met again). Called after a
  // map is built (EnforceQuotaNow, with the Scheduler's jobs) and at start-up. One run at a time.
  struct Evicted {
    uint32_t maps = 0;
    uint64_t bytes = 0;
    uint64_t bytes_after = 0;  // the store once they are gone
    bool met = true;
  };
  Evicted EnforceQuota(const std::vector<Scheduler::KnownJob>& jobs);
  // EnforceQuota with the Scheduler's jobs (nothing without a quota or a Scheduler). Call without
  // the Scheduler's lock and mu_.
  void EnforceQuotaNow();

  // Waits for a running assembly; no new ones.
  void Stop();

  struct Counters {
    uint64_t chunks_leased = 0, chunks_stored = 0, chunks_expired = 0, chunks_returned = 0, maps_built = 0,
             maps_left_to_workers = 0;
    // Verification: pieces traced again in full, pieces refused as not the coordinator's trace,
    // stored maps deleted because a convicted worker traced pieces of them.
    uint64_t chunks_verified_in_full = 0, chunks_refused = 0, maps_purged = 0;
    // The quota: maps evicted, and their bytes.
    uint64_t maps_evicted = 0, bytes_evicted = 0;
  };
  Counters counters() const;

 private:
  struct Chunk {
    using State = PieceState;  // moved only as PieceTransitions allows (map_states.h)
    State state = State::kQueued;
    std::string lease_id, worker_id;  // kLeased: its current lease (the Scheduler's LeaseTable) and holder
    uint32_t attempts = 0;
    // The distinct workers whose attempts failed (the piece is left to the workers after
    // max_attempts of them, as a task fails its job: scheduler.h), and failures of no worker.
    std::vector<std::string> failed_workers;
    uint32_t unattributed_failures = 0;
    std::string uploader;  // kDone: who traced it ("" if unknown: found on disk without a record)
  };
  struct Map {
    using State = MapState;  // moved only by SetStateLocked, as MapTransitions allows
    State state = State::kTracing;
    std::string key;
    uint64_t seq = 0;  // creation order: the Scheduler's queue serves pieces oldest map first
    std::string job_id;
    uint64_t map_index = 0, map_seed = 0;
    std::shared_ptr<const JobConfig> config;
    uint64_t photons = 0, chunk_photons = 0;
    std::vector<Chunk> chunks;
    size_t done = 0;
    BuiltMap built;
    std::set<std::pair<std::string, uint64_t>> waiting;  // (job, map index) to release once built
    std::set<std::string> contributors;                  // who traced its pieces (kBuilding, kBuilt)
    uint64_t generation = 0;  // bumped when a conviction purges it: an assembly under way is dropped
  };
  struct OnDisk {
    BuiltMap built;
    std::set<std::string> contributors;
  };
  // Under mu_.
  const std::string* KeyFor(const Job& job, uint64_t map_index);  // null: not distributed
  // The map of that key, created (its pieces in `update`) if it is new.
  Map& MapOf(const Job& job, uint64_t map_index, const std::string& key, MapUpdate& update);
  // The piece's attempt failed (`kind`: piece-failed, piece-expired, piece-refused): queued again, the
  // failure noted in `update` for the scheduler.
  void RequeueLocked(Map& map, uint32_t chunk, const std::string& kind, const std::string& why,
                     MapUpdate& update);
  void LeaveToWorkersLocked(Map& map, const std::string& why, MapUpdate& update);
  // A piece's file is named by its photon range, so pieces found on disk are reused only for the
  // same range (a coordinator restarted with another --map-chunk-photons traces its pieces anew).
  std::filesystem::path ChunkFile(const std::string& key, uint64_t begin, uint64_t end) const;
  void Scan();
  void Build(const std::string& key);  // on builder_

  // Why `chunk` (uploaded as `bytes`) is not the coordinator's trace of it, "" if it is (or the
  // scene cannot be loaded here): its first photons, or with `in_full` all of it (see the header
  // comment); `config`/`map_seed` of its map. Call without mu_ (it loads scenes and traces).
  std::string MismatchOf(const JobConfig& config, uint64_t map_seed, const PhotonChunk& chunk,
                         const std::string& bytes, bool in_full);
  // Who traced what (the `.by` files): read (empty if there is none), written before the file it
  // describes.
  static std::set<std::string> ReadTracers(const std::filesystem::path& file);
  static void WriteTracers(const std::filesystem::path& file, const std::set<std::string>& workers);
  // The job that created the map and every job waiting for it (health and convictions count in
  // each: the first may have ended).
  std::vector<std::string> JobsOfLocked(const Map& map) const;
  // A piece that is not the coordinator's trace: counted, and with `convict` its attempt failed (the
  // piece queued again) and its uploader convicted in every job of the map, then the failure
  // reported. Call without mu_ and check_mu_.
  void RefuseAndConvict(const std::string& key, uint32_t index, const std::string& lease_id,
                        const std::string& worker_id, const std::string& why);
  // Drops the scene CheckFirstPhotons keeps once no map of it is tracing.
  void ReleaseCheckSceneIfUnused();

  DistributedMapsOptions options_;
  const Clock& clock_;
  SceneDirectoryOf scene_directory_;
  Scheduler* scheduler_ = nullptr;
  mutable std::mutex mu_;
  std::map<std::string, Map> maps_;
  void SetStateLocked(Map& m, Map::State state);
  uint64_t next_seq_ = 1;
  std::unordered_set<std::string> uploading_;  // leases with an admitted upload stream
  // Per job and map index: the key of a distributed map.
  std::map<std::pair<std::string, uint64_t>, std::string> keys_;
  // kAuto jobs: the map indices more than one task uses.
  std::unordered_map<std::string, std::unordered_set<uint64_t>> shared_maps_;
  std::map<std::string, OnDisk> on_disk_;  // built maps found by Scan
  // Photon ranges found by Scan, with who traced them.
  std::map<std::string, std::map<std::pair<uint64_t, uint64_t>, std::string>> chunks_on_disk_;
  Counters counters_;
  // The quota: one EnforceQuota at a time (lock order: quota_mu_, then mu_); whether the quota was
  // found unmeetable (warned once until it is met again).
  std::mutex quota_mu_;
  bool quota_warned_ = false;
  // A map's use for the quota's order: its file's modification time set to now (map_quota.h).
  void TouchLocked(const std::string& key) const;
  // The scene of the last checked upload. Lock order: check_mu_, then mu_.
  std::mutex check_mu_;
  std::string check_scene_hash_;
  std::shared_ptr<const SceneRuntime> check_scene_;
  // The assemblies, one at a time on a thread of their own (never under the scheduler's lock), in
  // the order their last pieces arrived. Unbounded: a refused build would leave a map "building"
  // with no build pending (its render tasks held forever); a queued build is a key, and maps are
  // bounded by the jobs. Stop builds what is queued, then joins.
  void QueueBuild(const std::string& key);
  void BuildLoop();
  std::mutex build_mu_;
  std::condition_variable build_cv_;
  std::deque<std::string> build_queue_;
  bool build_stop_ = false;
  std::thread builder_;  // started by the constructor once the store is scanned, joined by Stop
};

// The content address of map `map_seed` of a job (see the header comment).
std::string DistributedMapKey(const JobConfig& config, uint64_t map_seed);
// Whether the job's maps may be traced once and stored (KeyFor's rule, before kAuto's choice).
bool MayDistributeMaps(const JobConfig& config);
// The map indices a plan's tasks use are below this (a dynamic plan's created tasks included).
uint64_t PlanMapCount(const PlanSpec& plan);

}  // namespace pf::server
