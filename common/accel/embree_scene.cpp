// Embree 3 back end. One device per process, created on first use with an error callback that
// logs; the scene is committed once and is then read-only (Embree: rtcCommitScene).
#include "common/accel/embree_scene.h"

#include <embree3/rtcore.h>
#if defined(__SSE2__)
#include <immintrin.h>
#endif
#include <spdlog/spdlog.h>

#include <atomic>
#include <bit>
#include <cstring>
#include <mutex>
#include <string>

#include "common/core/error.h"
#include "common/scene/surface_material.h"

namespace pf {
namespace {

// Embree calls this from whichever thread hit the error; we cannot throw through C code, so
// the message is logged and remembered, and the caller checks after each build step.
std::mutex g_error_mutex;
std::string g_last_error;

void OnEmbreeError(void* /*user*/, RTCError code, const char* message) {
  if (code == RTC_ERROR_NONE) return;
  spdlog::error("embree error {}: {}", int(code), message ? message : "");
  std::lock_guard lock(g_error_mutex);
  g_last_error = message ? message : "unknown Embree error";
}

void ThrowIfEmbreeFailed(RTCDevice device, const char* what) {
  const RTCError code = rtcGetDeviceError(device);
  if (code == RTC_ERROR_NONE) return;
  std::lock_guard lock(g_error_mutex);
  throw SystemError(std::string("Embree failed while ") + what + ": " + g_last_error);
}

// The process-wide device (Mitsuba and Embree's tutorials: one device, error callback first).
RTCDevice ProcessDevice() {
  static RTCDevice device = [] {
    RTCDevice d = rtcNewDevice(nullptr);
    if (!d) throw SystemError("cannot create an Embree device (rtcNewDevice failed)");
    rtcSetDeviceErrorFunction(d, OnEmbreeError, nullptr);
    return d;
  }();
  return device;
}

// The texture coordinates at barycentrics (u, v) of a triangle (scene.uvs non-empty).
TextureCoordinates InterpolatedUv(const SceneDescription& s, const std::array<uint32_t, 3>& tri, float u,
                                  float v) {
  const float w = 1.0f - u - v;
  const TextureCoordinates &a = s.uvs[tri[0]], &b = s.uvs[tri[1]], &c = s.uvs[tri[2]];
  return {a[0] * w + b[0] * u + c[0] * v, a[1] * w + b[1] * u + c[1] * v};
}

bool AnyAlphaMask(const SceneDescription& scene) {
  for (const Material& m : scene.materials)
    if (m.HasAlphaMask()) return true;
  return false;
}

}  // namespace

void EmbreeScene::CutOutFilter(const RTCFilterFunctionNArguments* args) {
  const auto* self = static_cast<const EmbreeScene*>(args->geometryUserPtr);
  const SceneDescription& s = *self->scene_;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const uint32_t triangle = RTCHitN_primID(args->hit, args->N, i);
    const Material& m = s.materials[s.triangle_material[triangle]];
    if (!m.HasAlphaMask()) continue;
    // The texture coordinates Intersect gives the same hit (the same barycentrics).
    const TextureCoordinates uv =
        s.uvs.empty() ? TextureCoordinates{0.0f, 0.0f}
                      : InterpolatedUv(s, s.triangles[triangle], RTCHitN_u(args->hit, args->N, i),
                                       RTCHitN_v(args->hit, args->N, i));
    if (IsCutOut(s, m, uv)) args->valid[i] = 0;
  }
}

struct EmbreeScene::EmbreeHandles {
  RTCScene scene = nullptr;
  ~EmbreeHandles() {
    if (scene) rtcReleaseScene(scene);
  }
};

EmbreeScene::EmbreeScene(const SceneDescription& scene)
    : scene_(&scene), embree_(std::make_unique<EmbreeHandles>()) {
  const size_t num_tris = scene.triangles.size();
  face_normals_.resize(num_tris);
  face_areas_.resize(num_tris);
  for (size_t i = 0; i < num_tris; ++i) {
    const auto& t = scene.triangles[i];
    const Vec3 c =
        Cross(scene.positions[t[1]] - scene.positions[t[0]], scene.positions[t[2]] - scene.positions[t[0]]);
    const float len = Length(c);
    face_areas_[i] = 0.5f * len;
    face_normals_[i] = len > 0 ? c / len : Vec3(0, 0, 1);
  }
  bounds_ = scene.ComputeBounds();
  // Floor for ray offsets near the origin of large scenes: a small fraction of the scene size.
  epsilon_ = bounds_.Empty() ? 1e-6f : std::max(MaxComponent(bounds_.Diagonal()) * 1e-6f, 1e-30f);

  RTCDevice device = ProcessDevice();
  embree_->scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(embree_->scene, RTC_BUILD_QUALITY_HIGH);
  if (num_tris > 0) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    // Copies (not shared buffers): Embree needs 16-byte-readable padding past the last vertex.
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), scene.positions.size()));
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), num_tris));
    ThrowIfEmbreeFailed(device, "allocating geometry buffers");
    for (size_t i = 0; i < scene.positions.size(); ++i) {
      vertices[3 * i + 0] = scene.positions[i].x;
      vertices[3 * i + 1] = scene.positions[i].y;
      vertices[3 * i + 2] = scene.positions[i].z;
    }
    for (size_t i = 0; i < num_tris; ++i) {
      for (int k = 0; k < 3; ++k) {
        if (scene.triangles[i][k] >= scene.positions.size())
          throw InputError("triangle " + std::to_string(i) + " references vertex " +
                           std::to_string(scene.triangles[i][k]) + " of " +
                           std::to_string(scene.positions.size()));
        indices[3 * i + k] = scene.triangles[i][k];
      }
    }
    if (AnyAlphaMask(scene)) {
      // Deterministic: whether a hit is cut out is a function of the hit alone.
      if (!rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED))
        throw SystemError(
            "the scene has alpha masks, and this Embree library was built without filter functions");
      rtcSetGeometryUserData(geom, this);
      rtcSetGeometryIntersectFilterFunction(geom, CutOutFilter);
      rtcSetGeometryOccludedFilterFunction(geom, CutOutFilter);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(embree_->scene, geom, 0);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(embree_->scene);
  ThrowIfEmbreeFailed(device, "building the BVH");
}

EmbreeScene::~EmbreeScene() = default;

namespace {

// Embree reads (org, tnear), (dir, time) and (tfar, mask, id, flags) as 16-byte vectors: written
// as one 16-byte store each, those reads are forwarded from the store buffer; written float by
// float, each ray's first loads waited for the stores to reach the cache (a store-forwarding
// stall: embree_bench's incoherent rays 8.2 → 11 M/s on Cornell, docs/results/kernel.md §4, Run 3).
void SetRay(const Ray& ray, RTCRay* r) {
#if defined(__SSE2__)
  _mm_store_ps(&r->org_x, _mm_setr_ps(ray.origin.x, ray.origin.y, ray.origin.z, 0.0f));
  _mm_store_ps(&r->dir_x, _mm_setr_ps(ray.direction.x, ray.direction.y, ray.direction.z, 0.0f));
  _mm_store_si128(reinterpret_cast<__m128i*>(&r->tfar),
                  _mm_setr_epi32(std::bit_cast<int>(ray.t_max), -1, 0, 0));  // tfar, mask, id, flags
#else
  r->org_x = ray.origin.x;
  r->org_y = ray.origin.y;
  r->org_z = ray.origin.z;
  r->tnear = 0.0f;
  r->dir_x = ray.direction.x;
  r->dir_y = ray.direction.y;
  r->dir_z = ray.direction.z;
  r->time = 0.0f;
  r->tfar = ray.t_max;
  r->mask = 0xffffffffu;
  r->id = 0;
  r->flags = 0;
#endif
}
// The closest hit of `ray` into *rh; false for a miss (Intersect and IntersectWalk).
bool IntersectClosest(RTCScene scene, const Ray& ray, RTCRayHit* rh) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  SetRay(ray, &rh->ray);
  rh->hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &context, rh);
  return rh->hit.geomID != RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

bool EmbreeScene::InterpolatedNormal(uint32_t triangle, float u, float v, const Vec3& ng, Vec3* n) const {
  const SceneDescription& s = *scene_;
  const auto& tri = s.triangles[triangle];
  const Vec3& n0 = s.normals[tri[0]];
  const Vec3& n1 = s.normals[tri[1]];
  const Vec3& n2 = s.normals[tri[2]];
  const Vec3 zero(0.0f);
  if (n0 == zero || n1 == zero || n2 == zero) return false;
  const float w = 1.0f - u - v;
  const Vec3 sum = n0 * w + n1 * u + n2 * v;
  const float len = Length(sum);
  if (!(len > 1e-12f && std::isfinite(len))) return false;
  const Vec3 unit = sum / len;
  // Shading normals live in the front face's hemisphere.
  *n = Dot(unit, ng) >= 0 ? unit : -unit;
  return true;
}

std::optional<SurfaceHit> EmbreeScene::Intersect(const Ray& ray) const {
  RTCRayHit rh;
  if (!IntersectClosest(embree_->scene, ray, &rh)) return std::nullopt;

  const SceneDescription& s = *scene_;
  SurfaceHit hit;
  hit.t = rh.ray.tfar;
  hit.triangle = rh.hit.primID;
  const auto& tri = s.triangles[hit.triangle];
  // On the triangle's plane to ½ ulp, which the ray offsets rely on (ray.h).
  hit.position = InterpolateOnTriangle(s.positions[tri[0]], s.positions[tri[1]], s.positions[tri[2]],
                                       rh.hit.u, rh.hit.v);
  hit.geometric_normal = face_normals_[hit.triangle];
  hit.front_face = Dot(ray.direction, hit.geometric_normal) < 0.0f;
  if (s.normals.empty() ||
      !InterpolatedNormal(hit.triangle, rh.hit.u, rh.hit.v, hit.geometric_normal, &hit.shading_normal))
    hit.shading_normal = hit.geometric_normal;
  hit.material = s.triangle_material[hit.triangle];
  if (!s.uvs.empty()) hit.uv = InterpolatedUv(s, tri, rh.hit.u, rh.hit.v);
  hit.light = s.triangle_light.empty() ? kNoLight : s.triangle_light[hit.triangle];
  return hit;
}

bool EmbreeScene::IntersectWalk(const Ray& ray, WalkHit* hit) const {
  RTCRayHit rh;
  if (!IntersectClosest(embree_->scene, ray, &rh)) return false;
  const SceneDescription& s = *scene_;
  const uint32_t triangle = rh.hit.primID;
  const auto& tri = s.triangles[triangle];
  hit->position = InterpolateOnTriangle(s.positions[tri[0]], s.positions[tri[1]], s.positions[tri[2]],
                                        rh.hit.u, rh.hit.v);
  hit->geometric_normal = face_normals_[triangle];
  hit->interpolated = !s.normals.empty() && InterpolatedNormal(triangle, rh.hit.u, rh.hit.v,
                                                               hit->geometric_normal, &hit->shading_normal);
  if (!hit->interpolated) hit->shading_normal = hit->geometric_normal;
  hit->material = s.triangle_material[triangle];
  if (!s.uvs.empty()) hit->uv = InterpolatedUv(s, tri, rh.hit.u, rh.hit.v);
  return true;
}

bool EmbreeScene::Occluded(const Ray& ray) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r;
  SetRay(ray, &r);
  rtcOccluded1(embree_->scene, &context, &r);
  return r.tfar < 0.0f;  // Embree sets tfar = -inf on occlusion
}

bool EmbreeScene::Visible(const Vec3& from, const Vec3& from_normal, const Vec3& to,
                          const Vec3& to_normal) const {
  const Vec3 d0 = to - from;
  const Vec3 o = OffsetRayOrigin(from, Dot(d0, from_normal) >= 0 ? from_normal : -from_normal, epsilon_);
  const Vec3 t = OffsetRayOrigin(to, Dot(d0, to_normal) <= 0 ? to_normal : -to_normal, epsilon_);
  const Vec3 d = t - o;
  const float dist = Length(d);
  if (!(dist > 0.0f)) return true;
  Ray ray{o, d / dist, dist};
  return !Occluded(ray);
}

}  // namespace pf
