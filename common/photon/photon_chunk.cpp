#include "common/photon/photon_chunk.h"

#include <cstring>
#include <stdexcept>

#include "common/core/byte_codec.h"
#include "common/photon/photon_maps_fill.h"

namespace pf {
namespace {

constexpr std::string_view kMagic = "PFCHNK\r\n";
constexpr uint32_t kVersion = 1;

// The lists of `kinds` of all chunks concatenated in order: what PhotonMaps::Build's
// MakeFilled adds to one map, already compressed; then built as it builds.
std::unique_ptr<PhotonMap> FillFromChunks(const PhotonMapsOptions& o, std::span<const PhotonChunk> chunks,
                                          std::initializer_list<PhotonKind> kinds,
                                          PhotonAttributes* attributes) {
  size_t n = 0;
  for (PhotonKind k : kinds)
    for (const PhotonChunk& c : chunks) n += c.lists[size_t(k)].photons.size();
  std::vector<Photon> compact;
  compact.reserve(n);
  for (PhotonKind k : kinds)
    for (const PhotonChunk& c : chunks)
      compact.insert(compact.end(), c.lists[size_t(k)].photons.begin(), c.lists[size_t(k)].photons.end());
  const auto in_order = [&] {
    PhotonAttributes a;
    for (PhotonKind k : kinds)
      for (const PhotonChunk& c : chunks) {
        const PhotonChunk::List& l = c.lists[size_t(k)];
        if (o.keep_light_ids) a.light.insert(a.light.end(), l.light.begin(), l.light.end());
        if (o.keep_origins) a.origin.insert(a.origin.end(), l.origin.begin(), l.origin.end());
      }
    return a;
  };
  return BuildPhotonMap(o, std::move(compact), in_order, attributes);
}

}  // namespace

PhotonChunk TracePhotonChunk(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options, uint64_t begin, uint64_t end) {
  PhotonTracerOptions to = options.tracing;
  to.photon_begin = begin;
  to.photon_end = end;
  if (end <= begin) throw std::invalid_argument("TracePhotonChunk: empty range");
  const PhotonTracingResult traced = TracePhotons(scene, lights, to);
  PhotonChunk chunk;
  chunk.begin = begin;
  chunk.end = end;
  chunk.rays = traced.rays;
  chunk.emitted_power = traced.emitted_power;
  chunk.light_ids = options.keep_light_ids;
  chunk.origins = options.keep_origins;
  const std::array<const TracedPhotons*, 3> from = {&traced.direct, &traced.indirect, &traced.caustic};
  // Direct photons that no map will hold (PhotonMapsOptions::direct_map) do not travel; their
  // power still counts in stored_power, as in a one-process PhotonMaps::Build.
  const bool drop_direct = options.separate_direct && !options.direct_map;
  for (int k = 0; k < 3; ++k) {
    PhotonChunk::List& list = chunk.lists[k];
    const bool drop = drop_direct && k == int(PhotonKind::kDirect);
    if (!drop) list.photons.reserve(from[k]->size());
    for (const TracedPhoton& p : *from[k]) {
      chunk.stored_power[0] += p.power.r;
      chunk.stored_power[1] += p.power.g;
      chunk.stored_power[2] += p.power.b;
      if (drop) continue;
      list.photons.push_back(Photon::Make(p.position, p.direction, p.power));
      if (chunk.light_ids) list.light.push_back(p.light);
      if (chunk.origins) list.origin.push_back(p.origin);
    }
  }
  return chunk;
}

std::string SerializePhotonChunk(const PhotonChunk& chunk) {
  std::string out;
  size_t photons = 0;
  for (const auto& l : chunk.lists) photons += l.photons.size();
  out.reserve(128 + photons * (sizeof(Photon) + 16));
  ByteWriter w(out);
  w.PutBytes(kMagic);
  w.Put<uint32_t>(kVersion);
  w.Put<uint64_t>(chunk.begin);
  w.Put<uint64_t>(chunk.end);
  w.Put<uint64_t>(chunk.rays);
  for (double p : chunk.stored_power) w.Put<double>(p);
  w.Put<float>(chunk.emitted_power.r);
  w.Put<float>(chunk.emitted_power.g);
  w.Put<float>(chunk.emitted_power.b);
  w.Put<uint8_t>(chunk.light_ids);
  w.Put<uint8_t>(chunk.origins);
  w.Put<uint16_t>(0);
  for (const PhotonChunk::List& l : chunk.lists) {
    const uint64_t n = l.photons.size();
    if ((chunk.light_ids && l.light.size() != n) || (chunk.origins && l.origin.size() != n))
      throw std::logic_error("SerializePhotonChunk: attributes do not match the photons");
    w.Put<uint64_t>(n);
    w.PutBytes(std::string_view(reinterpret_cast<const char*>(l.photons.data()), n * sizeof(Photon)));
    if (chunk.light_ids) w.PutArray<uint32_t>(l.light);
    if (chunk.origins)
      for (const Vec3& o : l.origin) {
        w.Put<float>(o.x);
        w.Put<float>(o.y);
        w.Put<float>(o.z);
      }
  }
  return out;
}

PhotonChunk DeserializePhotonChunk(std::string_view bytes) {
  if (bytes.substr(0, kMagic.size()) != kMagic) throw InputError("photon chunk: bad magic");
  ByteReader r(bytes.substr(kMagic.size()), "photon chunk");
  if (const uint32_t v = r.Get<uint32_t>(); v != kVersion) r.Fail("format version " + std::to_string(v));
  PhotonChunk chunk;
  chunk.begin = r.Get<uint64_t>();
  chunk.end = r.Get<uint64_t>();
  chunk.rays = r.Get<uint64_t>();
  for (double& p : chunk.stored_power) p = r.Get<double>();
  chunk.emitted_power.r = r.Get<float>();
  chunk.emitted_power.g = r.Get<float>();
  chunk.emitted_power.b = r.Get<float>();
  const uint8_t lights = r.Get<uint8_t>(), origins = r.Get<uint8_t>();
  if (lights > 1 || origins > 1 || r.Get<uint16_t>() != 0) r.Fail("malformed header");
  if (chunk.end <= chunk.begin || chunk.begin % kPhotonTracingChunk != 0) r.Fail("bad photon range");
  chunk.light_ids = lights;
  chunk.origins = origins;
  for (PhotonChunk::List& l : chunk.lists) {
    const uint64_t n = r.Get<uint64_t>();
    // Checked before allocating: a corrupt count must not allocate what the bytes cannot hold
    // (divided, not multiplied: a huge count must not wrap). Not bounded by the photons emitted:
    // a photon is stored at every diffuse bounce, so a bright closed room stores several per
    // emitted photon (the furnace at albedo 0.8: ~4; test PhotonChunk.MoreStoredThanEmitted…).
    if (n > r.remaining() / (sizeof(Photon) + 4 * lights + 12 * origins))
      r.Fail("truncated or corrupt list of " + std::to_string(n) + " photons");
    l.photons.resize(n);
    const std::string_view b = r.GetBytes(n * sizeof(Photon));
    if (n > 0) std::memcpy(l.photons.data(), b.data(), b.size());
    for (const Photon& p : l.photons)
      if (!IsFinite(p.Position())) r.Fail("non-finite photon position");
    if (lights) {
      l.light.resize(n);
      r.GetArray<uint32_t>(l.light);
    }
    if (origins) {
      l.origin.resize(n);
      for (Vec3& o : l.origin) {
        o.x = r.Get<float>();
        o.y = r.Get<float>();
        o.z = r.Get<float>();
      }
    }
  }
  if (!r.empty()) r.Fail(std::to_string(r.remaining()) + " trailing bytes");
  return chunk;
}

PhotonMaps AssemblePhotonMaps(std::span<const PhotonChunk> chunks, const PhotonMapsOptions& options) {
  if (options.caustic == CausticMapMode::kAuto)
    throw std::logic_error("AssemblePhotonMaps: the caustic map mode must be resolved");
  uint64_t next = 0;
  for (const PhotonChunk& c : chunks) {
    if (c.begin != next)
      throw InputError("photon chunks: photons [" + std::to_string(next) + ", " + std::to_string(c.begin) +
                       ") are missing");
    if ((options.keep_light_ids && !c.light_ids) || (options.keep_origins && !c.origins))
      throw InputError("photon chunks: a chunk lacks the light ids or origins the maps need");
    next = c.end;
  }
  if (next != options.tracing.photons)
    throw InputError("photon chunks: cover " + std::to_string(next) + " of " +
                     std::to_string(options.tracing.photons) + " photons");
  PhotonMaps maps;
  maps.seed = options.tracing.map_seed;
  maps.stats.emitted = options.tracing.photons;
  if (options.tracing.caustic_split > 1 && options.tracing.caustic_split_method == CausticSplitMethod::kBrute)
    maps.stats.emitted *= options.tracing.caustic_split;  // S·N left the lights (§4.6.1)
  double power[3] = {0, 0, 0};
  for (const PhotonChunk& c : chunks) {
    maps.stats.rays += c.rays;
    for (int i = 0; i < 3; ++i) power[i] += c.stored_power[i];
  }
  maps.stats.stored_power = Rgb(float(power[0]), float(power[1]), float(power[2]));
  if (!chunks.empty()) maps.stats.emitted_power = chunks.front().emitted_power;
  std::array<uint64_t, 3> counts{};
  for (const PhotonChunk& c : chunks)
    for (size_t k = 0; k < 3; ++k) counts[k] += c.lists[k].photons.size();
  FillPhotonMaps(
      options, options.caustic == CausticMapMode::kOn, counts,
      [&](std::initializer_list<PhotonKind> kinds, PhotonAttributes* attributes) {
        return FillFromChunks(options, chunks, kinds, attributes);
      },
      &maps);
  return maps;
}

}  // namespace pf
