#pragma once
// The photon map benchmark's workloads (bench/photon_map_bench.cpp): the photons and query points
// every structure is measured on. Synthetic (a Cornell-box-like room, no tracer needed) and
// traced (real photons from the photon tracer and the hits of the manifest camera's rays, cached
// on disk between runs). Split from the benchmark itself, which holds the measurements.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon.h"
#include "common/photon/photon_map.h"
#include "common/photon/photon_tracer.h"
#include "common/scene/scene_loader.h"

namespace pf::bench {

// ---------------------------------------------------------------------------------------
// Synthetic workload (--synthetic): a Cornell-box-like room, 5.5 units on a side, y up.

struct Quad {  // the parallelogram origin + s·u + t·v, s, t ∈ [0, 1]
  Vec3 origin, u, v;
  float Area() const { return Length(Cross(u, v)); }
  Vec3 Point(float s, float t) const { return origin + u * s + v * t; }
};

inline std::vector<Quad> RoomQuads() {
  const float w = 5.5f;
  std::vector<Quad> quads = {
      {{0, 0, 0}, {w, 0, 0}, {0, 0, w}},  // floor
      {{0, w, 0}, {w, 0, 0}, {0, 0, w}},  // ceiling
      {{0, 0, w}, {w, 0, 0}, {0, w, 0}},  // back
      {{0, 0, 0}, {w, 0, 0}, {0, w, 0}},  // front
      {{0, 0, 0}, {0, 0, w}, {0, w, 0}},  // left
      {{w, 0, 0}, {0, 0, w}, {0, w, 0}},  // right
  };
  // Two boxes rotated about y, like the classic short and tall blocks: 4 sides + top each.
  auto add_box = [&quads](Vec3 centre, float half, float height, float angle) {
    const Vec3 a(std::cos(angle) * half, 0, std::sin(angle) * half);
    const Vec3 b(-std::sin(angle) * half, 0, std::cos(angle) * half);
    const Vec3 corners[4] = {centre - a - b, centre + a - b, centre + a + b, centre - a + b};
    for (int i = 0; i < 4; ++i)
      quads.push_back({corners[i], corners[(i + 1) % 4] - corners[i], {0, height, 0}});
    quads.push_back({corners[0] + Vec3(0, height, 0), a * 2.0f, b * 2.0f});
  };
  add_box({1.85f, 0, 1.7f}, 0.83f, 1.65f, -0.29f);
  add_box({3.7f, 0, 3.5f}, 0.83f, 3.3f, 0.3f);
  return quads;
}

class SurfaceSampler {
 public:
  explicit SurfaceSampler(std::vector<Quad> quads) : quads_(std::move(quads)) {
    float total = 0;
    for (const Quad& q : quads_) cdf_.push_back(total += q.Area());
    for (float& c : cdf_) c /= total;
  }
  Vec3 Uniform(Rng& rng) const {
    const float r = rng.Uniform();
    const std::size_t i = std::min<std::size_t>(std::lower_bound(cdf_.begin(), cdf_.end(), r) - cdf_.begin(),
                                                quads_.size() - 1);
    return quads_[i].Point(rng.Uniform(), rng.Uniform());
  }

 private:
  std::vector<Quad> quads_;
  std::vector<float> cdf_;
};

const Vec3 kLight(2.75f, 5.45f, 2.75f);
// Caustic-like blobs on the floor (e.g. under a glass sphere): centre and sigma.
const std::pair<Vec3, float> kCaustics[] = {
    {{3.0f, 0.0f, 1.2f}, 0.03f}, {{1.0f, 0.0f, 3.6f}, 0.06f}, {{4.6f, 0.0f, 1.0f}, 0.12f}};

inline float Gauss(Rng& rng) {
  const float u = std::max(rng.Uniform(), 1e-7f), v = rng.Uniform();
  return std::sqrt(-2.0f * std::log(u)) * std::cos(kTwoPi * v);
}

inline Vec3 CausticPoint(Rng& rng) {
  const auto& [centre, sigma] = kCaustics[rng.UniformInt(3)];
  const float x = std::clamp(centre.x + sigma * Gauss(rng), 0.0f, 5.5f);
  const float z = std::clamp(centre.z + sigma * Gauss(rng), 0.0f, 5.5f);
  return {x, 0.0f, z};
}

inline std::vector<Photon> MakeSyntheticPhotons(std::size_t n, uint64_t seed) {
  const SurfaceSampler surfaces(RoomQuads());
  Rng rng = Rng::ForKey(HashKey(seed, 1));
  std::vector<Photon> photons;
  photons.reserve(n);
  while (photons.size() < n) {
    Vec3 p;
    if (rng.Uniform() < 0.1f) {
      p = CausticPoint(rng);
    } else {
      // Density falls off with the distance to the light (rejection sampling).
      p = surfaces.Uniform(rng);
      const float d2 = LengthSquared(p - kLight);
      if (rng.Uniform() > 1.0f / (1.0f + d2 / 9.0f)) continue;
    }
    const float phi = kTwoPi * rng.Uniform(), cos_t = std::sqrt(rng.Uniform());
    const float sin_t = std::sqrt(1.0f - cos_t * cos_t);
    const Vec3 dir(sin_t * std::cos(phi), -cos_t, sin_t * std::sin(phi));
    photons.push_back(Photon::Make(p, dir, Rgb(1e-6f, 0.8e-6f, 0.6e-6f) * (0.5f + rng.Uniform())));
  }
  return photons;
}

inline std::vector<Vec3> MakeSyntheticQueries(std::size_t n, uint64_t seed) {
  const SurfaceSampler surfaces(RoomQuads());
  Rng rng = Rng::ForKey(HashKey(seed, 2));
  std::vector<Vec3> q;
  q.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    q.push_back(rng.Uniform() < 0.1f ? CausticPoint(rng) : surfaces.Uniform(rng));
  return q;
}

// ---------------------------------------------------------------------------------------
// Real workload: traced photons and camera-ray hits.

struct TraceInfo {
  uint64_t emitted = 0;  // photons emitted to get `stored`
  uint64_t stored = 0;   // photons stored by the walk (≥ N); N of them are kept
  uint64_t direct = 0, indirect = 0, caustic = 0;
  double seconds = 0;  // tracing wall time (all threads), 0 if from the cache
  bool cached = false;
};

class Workload {
 public:
  virtual ~Workload() = default;
  virtual std::string name() const = 0;
  virtual std::string description() const = 0;
  virtual std::vector<Photon> Photons(std::size_t n, TraceInfo* info) = 0;
  virtual const std::vector<Vec3>& Queries() = 0;
};

class SyntheticWorkload final : public Workload {
 public:
  std::string name() const override { return "synthetic"; }
  std::string description() const override {
    return "SYNTHETIC photons on the surfaces of a Cornell-box-like room (6 walls + 2 rotated boxes, density "
           "falling off from the ceiling light) + 10% in caustic-like gaussian blobs on the floor; queries "
           "uniform "
           "by area on the same surfaces, 10% in the blobs (stand-ins for camera-ray hits)";
  }
  std::vector<Photon> Photons(std::size_t n, TraceInfo*) override { return MakeSyntheticPhotons(n, 1999); }
  const std::vector<Vec3>& Queries() override {
    if (queries_.empty()) queries_ = MakeSyntheticQueries(65536, 2024);
    return queries_;
  }

 private:
  std::vector<Vec3> queries_;
};

// Raw cache files: a 56-byte header (magic, element count, 5 numbers describing the content)
// and the elements.
constexpr uint64_t kCacheMagic = 0x70686f746f6e3032ull;
template <typename T>
inline bool ReadCache(const std::filesystem::path& path, std::vector<T>* out, uint64_t extra[5]) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  uint64_t header[7];
  if (!in.read(reinterpret_cast<char*>(header), sizeof header) || header[0] != kCacheMagic) return false;
  out->resize(header[1]);
  for (int i = 0; i < 5; ++i) extra[i] = header[2 + i];
  return bool(in.read(reinterpret_cast<char*>(out->data()), std::streamsize(out->size() * sizeof(T))));
}
template <typename T>
inline void WriteCache(const std::filesystem::path& path, const std::vector<T>& v, const uint64_t extra[5]) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  const uint64_t header[7] = {kCacheMagic, v.size(), extra[0], extra[1], extra[2], extra[3], extra[4]};
  out.write(reinterpret_cast<const char*>(header), sizeof header);
  out.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(T)));
}

class SceneWorkload final : public Workload {
 public:
  static constexpr uint64_t kMapSeed = 1;
  static constexpr int kQueryRows = 256;  // the larger image side

  SceneWorkload(std::string name, std::filesystem::path manifest, std::string cache_dir)
      : name_(std::move(name)), manifest_(std::move(manifest)), cache_dir_(std::move(cache_dir)) {}

  std::string name() const override { return name_; }
  std::string description() const override {
    return "REAL photons traced in " + manifest_.filename().string() +
           " (photon_tracer.h, map seed 1; direct + indirect + caustic photons, evenly thinned to N); "
           "queries: "
           "hits of the manifest camera's primary rays, 1 jittered ray per pixel, larger side 256 px, "
           "scan-line "
           "order";
  }

  std::vector<Photon> Photons(std::size_t n, TraceInfo* info) override {
    const std::filesystem::path cache =
        cache_dir_.empty()
            ? std::filesystem::path()
            : std::filesystem::path(cache_dir_) / (name_ + "-" + std::to_string(n) + ".photons");
    std::vector<Photon> photons;
    uint64_t extra[5] = {0, 0, 0, 0, 0};
    if (!cache.empty() && ReadCache(cache, &photons, extra) && photons.size() == n) {
      *info = TraceInfo{extra[0], extra[1], extra[2], extra[3], extra[4], 0.0, true};
      return photons;
    }
    Load();
    // Pilot run: the stored-per-emitted ratio, then emit enough for N with a 2% margin.
    PhotonTracerOptions options;
    options.map_seed = 999;
    options.photons = 20000;
    options.threads = 0;
    const PhotonTracingResult pilot = TracePhotons(*accel_, *lights_, options);
    const double ratio =
        double(pilot.direct.size() + pilot.indirect.size() + pilot.caustic.size()) / double(pilot.emitted);
    options.map_seed = kMapSeed;
    options.photons = uint64_t(std::ceil(double(n) / ratio * 1.02)) + 100;
    for (;;) {
      const auto t0 = std::chrono::steady_clock::now();
      PhotonTracingResult traced = TracePhotons(*accel_, *lights_, options);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const std::size_t m = traced.direct.size() + traced.indirect.size() + traced.caustic.size();
      if (m < n) {
        options.photons =
            uint64_t(double(options.photons) * 1.05 * double(n) / double(std::max<std::size_t>(m, 1)));
        continue;
      }
      *info =
          TraceInfo{traced.emitted, m,    traced.direct.size(), traced.indirect.size(), traced.caustic.size(),
                    seconds,        false};
      // Even thinning of the concatenation to exactly N: keeps each kind's share and, within a
      // kind, the photons of every light stratum (the tracer stratifies lights over the index).
      photons.reserve(n);
      std::size_t j = 0;
      for (const auto* list : {&traced.direct, &traced.indirect, &traced.caustic}) {
        for (const TracedPhoton& p : *list) {
          if ((j + 1) * n / m > j * n / m) photons.push_back(Photon::Make(p.position, p.direction, p.power));
          ++j;
        }
      }
      break;
    }
    if (!cache.empty()) {
      const uint64_t counts[5] = {info->emitted, info->stored, info->direct, info->indirect, info->caustic};
      WriteCache(cache, photons, counts);
    }
    return photons;
  }

  const std::vector<Vec3>& Queries() override {
    if (!queries_.empty()) return queries_;
    const std::filesystem::path cache = cache_dir_.empty()
                                            ? std::filesystem::path()
                                            : std::filesystem::path(cache_dir_) / (name_ + ".queries");
    uint64_t extra[5] = {0, 0, 0, 0, 0};
    if (!cache.empty() && ReadCache(cache, &queries_, extra) && !queries_.empty()) {
      width_ = int(extra[0]);
      height_ = int(extra[1]);
      return queries_;
    }
    Load();
    CameraSpec spec = scene_.cameras.empty() ? DefaultCamera(scene_) : scene_.cameras.front();
    const double scale = double(kQueryRows) / double(std::max(spec.width, spec.height));
    spec.width = std::max(1, int(std::lround(spec.width * scale)));
    spec.height = std::max(1, int(std::lround(spec.height * scale)));
    width_ = spec.width;
    height_ = spec.height;
    const Camera camera(spec, scene_.origin);
    for (int y = 0; y < spec.height; ++y) {
      for (int x = 0; x < spec.width; ++x) {
        Rng rng = Rng::ForKey(HashKey(2024, uint64_t(y), uint64_t(x)));
        const float u = rng.Uniform(), v = rng.Uniform();
        if (const auto hit = accel_->Intersect(camera.GenerateRay(x, y, u, v)))
          queries_.push_back(hit->position);
      }
    }
    if (!cache.empty()) {
      extra[0] = uint64_t(width_);
      extra[1] = uint64_t(height_);
      WriteCache(cache, queries_, extra);
    }
    return queries_;
  }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  void Load() {
    if (accel_) return;
    scene_ = LoadScene(manifest_);
    accel_ = std::make_unique<EmbreeScene>(scene_);
    lights_ = std::make_unique<LightSampler>(*accel_);
  }

  std::string name_;
  std::filesystem::path manifest_;
  std::string cache_dir_;
  SceneDescription scene_;
  std::unique_ptr<EmbreeScene> accel_;
  std::unique_ptr<LightSampler> lights_;
  std::vector<Vec3> queries_;
  int width_ = 0, height_ = 0;
};

}  // namespace pf::bench
