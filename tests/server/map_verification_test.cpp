// Verification of map pieces (server/scheduling/distributed_maps.h; docs/farm.md "Result
// verification") through a real in-process coordinator: a piece whose photons past the always
// checked first 4096 were moved is refused when it is traced again in full, and its uploader
// convicted; when it was not traced in full (the fraction is a fraction), a later conviction of its
// uploader deletes every stored map holding its pieces — in memory or found on disk after a
// restart — restarts the jobs that used them, and the map traced again is the honest one, with
// another digest.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "common/core/sha256.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_bundle.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/scheduler.h"
#include "server/store/scene_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
using testing::TakeLease;
using testing::TempDir;
namespace v1 = photonfarm::v1;
namespace fs = std::filesystem;

// The piece's upload; the checksums are the forger's own: they match its bytes. ABORTED if the
// coordinator did not accept it.
grpc::Status UploadPiece(LiveCoordinator& live, const v1::Task& piece, const std::string& worker,
                         const std::string& bytes) {
  bool accepted = false;
  const grpc::Status st = testing::UploadPiece(live, piece.lease_id(), worker, bytes, &accepted);
  if (st.ok() && !accepted) return grpc::Status(grpc::StatusCode::ABORTED, "not accepted");
  return st;
}

class MapVerificationTest : public ::testing::Test {
 protected:
  void Start(double piece_fraction) {
    CoordinatorOptions o;
    o.data_dir = dir_.path() / "data";
    o.verify_fraction = 0;
    o.verify_outliers = false;
    o.verify_piece_fraction = piece_fraction;
    o.map_chunk_photons = 8192;
    live_.reset();
    live_ = std::make_unique<LiveCoordinator>(o);
    hash_ = testing::UploadCornell(*live_);
  }

  // One distributed map of 16384 photons in two pieces of 8192, one render task.
  std::string Submit() {
    v1::JobSpec spec;
    spec.set_scene_hash(hash_);
    spec.mutable_camera()->set_width(24);
    spec.mutable_camera()->set_height(18);
    spec.mutable_settings()->set_integrator(v1::INTEGRATOR_PHOTONMAP);
    spec.mutable_settings()->mutable_photon_map()->set_photons(16384);
    spec.mutable_settings()->mutable_photon_map()->set_k(20);
    spec.mutable_settings()->mutable_photon_map()->set_map_tracing(v1::MAP_TRACING_DISTRIBUTED);
    spec.mutable_plan()->mutable_multiple_maps()->set_maps(1);
    spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
    spec.set_seed(5);
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    v1::SubmitJobResponse resp;
    EXPECT_TRUE(live_->render->SubmitJob(Ctx().get(), req, &resp).ok());
    return resp.job_id();
  }

  PhotonMapsOptions MapOptions(const v1::Task& piece) {
    if (!scene_)
      scene_ = std::make_unique<SceneRuntime>(
          LoadBundle(live_->coordinator->scenes().DirectoryOf(hash_), piece.scene_entry()));
    PhotonMapsOptions mo =
        SettingsFromProto(piece.settings(), "settings").Resolved(scene_->description).MapsOptions();
    mo.tracing.map_seed = piece.map_seed();
    mo.tracing.threads = 1;  // as the coordinator assembles (--map-build-threads 1)
    return mo;
  }
  PhotonChunk Trace(const v1::Task& piece) {
    const PhotonMapsOptions mo = MapOptions(piece);
    return TracePhotonChunk(scene_->accel, scene_->lights, mo, piece.trace_chunk().photon_begin(),
                            piece.trace_chunk().photon_end());
  }
  // The forger's piece: honest, then the last quarter of each list moved by a millimetre.
  static std::string Shifted(PhotonChunk chunk) {
    for (PhotonChunk::List& list : chunk.lists)
      for (size_t i = list.photons.size() - list.photons.size() / 4; i < list.photons.size(); ++i)
        list.photons[i].position[0] += 1e-3f;
    return SerializePhotonChunk(chunk);
  }
  v1::JobStatus Status(const std::string& id) { return live_->coordinator->scheduler().Status(id); }
  int Events(const std::string& id, const std::string& kind, const std::string& worker) {
    int n = 0;
    for (const v1::TaskEvent& e : live_->coordinator->scheduler().activity().Events(id))
      n += e.kind() == kind && e.worker_id() == worker;
    return n;
  }
  // The render task of `job` (waits for its map to be built and its restart, if any, to be stored).
  v1::Task RenderTask(const std::string& worker) {
    for (int i = 0; i < 100; ++i) {
      std::optional<v1::Task> t = TakeLease(*live_, worker, 0.2);
      if (t && !t->has_trace_chunk()) return *t;
      EXPECT_FALSE(t.has_value()) << "a piece was left: " << t->trace_chunk().chunk_index();
    }
    ADD_FAILURE() << "no render task";
    return {};
  }
  std::string MapBytes(const std::string& key) {
    const std::optional<fs::path> file = live_->coordinator->maps().MapFile(key);
    if (!file) return "";
    std::ifstream in(*file, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }

  TempDir dir_;
  std::unique_ptr<LiveCoordinator> live_;
  std::string hash_;
  std::unique_ptr<SceneRuntime> scene_;
};

// Traced again in full (fraction 1): the forged piece is refused, its uploader convicted
// (blocklisted for the job, event), the piece traced by another worker, the job ends well.
TEST_F(MapVerificationTest,
       APieceForgedPastItsCheckedPrefixIsRefusedWhenTracedInFullAndItsUploaderConvicted) {
  Start(1.0);
  const std::string id = Submit();
  const std::optional<v1::Task> piece = TakeLease(*live_, "forger", 5);
  ASSERT_TRUE(piece && piece->has_trace_chunk());
  const grpc::Status st = UploadPiece(*live_, *piece, "forger", Shifted(Trace(*piece)));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("differs from the trace of all of them"));
  const v1::JobStatus s = Status(id);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "forger");
  EXPECT_EQ(Events(id, "convicted", "forger"), 1);
  EXPECT_FALSE(TakeLease(*live_, "forger").has_value()) << "no more pieces of this job";
  for (int i = 0; i < 2; ++i) {
    const std::optional<v1::Task> p = TakeLease(*live_, "honest", 5);
    ASSERT_TRUE(p && p->has_trace_chunk());
    ASSERT_TRUE(UploadPiece(*live_, *p, "honest", SerializePhotonChunk(Trace(*p))).ok());
  }
  EXPECT_EQ(live_->coordinator->maps().counters().chunks_verified_in_full, 2u);
  const v1::Task render = RenderTask("honest");
  ASSERT_TRUE(render.has_map());
  v1::CompleteTaskRequest req;
  req.set_lease_id(render.lease_id());
  req.set_worker_id("honest");
  req.mutable_rgb_sums()->Resize(24 * 18 * 3, 0.5f);
  v1::CompleteTaskResponse resp;
  ASSERT_TRUE(live_->worker->CompleteTask(Ctx().get(), req, &resp).ok());
  EXPECT_TRUE(resp.merged());
  EXPECT_EQ(Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// Not traced in full (fraction 0): the forged piece passes — what a malicious worker can still do —
// and two jobs render with the poisoned map. Once its uploader is convicted (here directly, as a
// render verification's mismatch would), the map is deleted, both jobs restart without it, and the
// map traced again is the honest map, byte for byte, under another digest (MapRef.digest: no
// worker's cache serves the old one).
TEST_F(MapVerificationTest, AConvictedWorkersPiecesLeaveEveryStoredMapAndItsJobsRestart) {
  Start(0.0);
  const std::string a = Submit();
  const std::optional<v1::Task> p0 = TakeLease(*live_, "forger", 5);
  ASSERT_TRUE(p0 && p0->has_trace_chunk());
  ASSERT_TRUE(UploadPiece(*live_, *p0, "forger", Shifted(Trace(*p0))).ok())
      << "its first 4096 photons are right";
  const std::optional<v1::Task> p1 = TakeLease(*live_, "honest", 5);
  ASSERT_TRUE(p1 && p1->has_trace_chunk());
  ASSERT_TRUE(UploadPiece(*live_, *p1, "honest", SerializePhotonChunk(Trace(*p1))).ok());
  const v1::Task render_a = RenderTask("honest");
  ASSERT_TRUE(render_a.has_map());
  const std::string key = render_a.map().map_key(), poisoned = render_a.map().digest();
  const std::string b = Submit();  // the same scene, settings and seed: the same map
  const v1::Task render_b = RenderTask("honest");
  EXPECT_EQ(render_b.job_id(), b);
  EXPECT_EQ(render_b.map().digest(), poisoned);

  ASSERT_TRUE(live_->coordinator->scheduler().ConvictWorker(a, "forger", 0, "a render differed"));
  EXPECT_EQ(MapBytes(key), "") << "the poisoned map is deleted";
  EXPECT_EQ(live_->coordinator->maps().counters().maps_purged, 1u);
  for (const std::string& id : {a, b}) {
    EXPECT_EQ(live_->coordinator->scheduler().JobEpoch(id), 1u) << id << " restarted";
    const v1::JobStatus s = Status(id);
    ASSERT_EQ(s.blocklisted_workers_size(), 1) << id;
    EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "forger");
  }
  // Traced again from nothing, without the forger.
  EXPECT_FALSE(TakeLease(*live_, "forger").has_value());
  std::vector<PhotonChunk> honest;
  for (int i = 0; i < 2; ++i) {
    const std::optional<v1::Task> p = TakeLease(*live_, "honest", 5);
    ASSERT_TRUE(p && p->has_trace_chunk());
    honest.push_back(Trace(*p));
    ASSERT_TRUE(UploadPiece(*live_, *p, "honest", SerializePhotonChunk(honest.back())).ok());
  }
  const v1::Task again = RenderTask("honest");
  ASSERT_TRUE(again.has_map());
  EXPECT_EQ(again.map().map_key(), key);
  EXPECT_NE(again.map().digest(), poisoned);
  std::sort(honest.begin(), honest.end(),
            [](const PhotonChunk& x, const PhotonChunk& y) { return x.begin < y.begin; });
  // Byte for byte but for the build's timings (two f64 after the counts) and the digest over them.
  std::string stored = MapBytes(key),
              expected = SerializePhotonMaps(AssemblePhotonMaps(honest, MapOptions(*p1)));
  ASSERT_EQ(stored.size(), expected.size());
  for (std::string* bytes : {&stored, &expected}) {
    bytes->replace(60, 16, 16, '\0');
    bytes->resize(bytes->size() - 32);
  }
  EXPECT_TRUE(stored == expected) << "the stored map is the honest one";
}

// The record of who traced a stored map survives a restart: a map built from a forged piece and
// found on disk by the next coordinator is deleted when its uploader is convicted there.
TEST_F(MapVerificationTest, AStoredMapFoundAfterARestartIsDeletedWhenItsTracerIsConvicted) {
  Start(0.0);
  Submit();
  const std::optional<v1::Task> p0 = TakeLease(*live_, "forger", 5);
  ASSERT_TRUE(p0 && p0->has_trace_chunk());
  ASSERT_TRUE(UploadPiece(*live_, *p0, "forger", Shifted(Trace(*p0))).ok());
  const std::optional<v1::Task> p1 = TakeLease(*live_, "honest", 5);
  ASSERT_TRUE(p1 && p1->has_trace_chunk());
  ASSERT_TRUE(UploadPiece(*live_, *p1, "honest", SerializePhotonChunk(Trace(*p1))).ok());
  const std::string key = RenderTask("honest").map().map_key();
  ASSERT_NE(MapBytes(key), "");

  Start(0.0);  // the same data directory
  const std::string c = Submit();
  const v1::Task render = RenderTask("honest");  // the resumed first job's or c's: the same map
  ASSERT_TRUE(render.has_map()) << "the map found on disk";
  EXPECT_EQ(render.map().map_key(), key);
  ASSERT_TRUE(live_->coordinator->scheduler().ConvictWorker(c, "forger", 0, "a render differed"));
  EXPECT_EQ(MapBytes(key), "");
  EXPECT_FALSE(fs::exists(dir_.path() / "data" / "maps" / (key + ".pfmaps")));
  const std::optional<v1::Task> p = TakeLease(*live_, "honest", 5);
  EXPECT_TRUE(p && p->has_trace_chunk()) << "traced again";
}

}  // namespace
}  // namespace pf::server
