#include "common/photon/photon_chunk.h"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cstring>
#include <stdexcept>

#include "common/core/byte_codec.h"
#include "common/photon/photon_map_factory.h"

namespace pf {
namespace {

constexpr std::string_view kMagic = "PFCHNK\r\n";
constexpr uint32_t kVersion = 2;

// One map of `o` from the lists of `kinds` of all chunks, concatenated in that order (kind by
// kind, each in photon order: the lists a whole trace gives; the order decides the balanced
// tree), built. The photons go from the chunks straight into the map. With keep_light_ids /
// keep_origins, their attributes are gathered in the same order once the map is built (so a
// concatenated copy and the build's memory never peak together) and stored in the map's
// post-build order in `attributes`.
std::unique_ptr<PhotonMap> FillFromChunks(const PhotonMapsOptions& o, std::span<const PhotonChunk> chunks,
                                          std::initializer_list<PhotonKind> kinds,
                                          PhotonAttributes* attributes) {
  auto map = MakePhotonMap(o.kind, o.structure);
  map->set_build_threads(o.tracing.threads);
  size_t n = 0;
  for (PhotonKind k : kinds)
    for (const PhotonChunk& c : chunks) n += c.lists[size_t(k)].photons.size();
  map->Reserve(n);
  for (PhotonKind k : kinds)
    for (const PhotonChunk& c : chunks) map->AddPhotons(c.lists[size_t(k)].photons);
  if (!o.keep_light_ids && !o.keep_origins) {
    map->PrepareForQuery();
    return map;
  }
  std::vector<uint32_t> original;
  map->PrepareForQuery(&original);
  // The attributes in photon order: one list's own (a local build's map of one kind), else the
  // lists concatenated.
  PhotonChunk::List joined;
  const PhotonChunk::List* in_order = &joined;
  if (chunks.size() == 1 && kinds.size() == 1) {
    in_order = &chunks.front().lists[size_t(*kinds.begin())];
  } else {
    for (PhotonKind k : kinds)
      for (const PhotonChunk& c : chunks) {
        const PhotonChunk::List& l = c.lists[size_t(k)];
        if (o.keep_light_ids) joined.light.insert(joined.light.end(), l.light.begin(), l.light.end());
        if (o.keep_origins) joined.origin.insert(joined.origin.end(), l.origin.begin(), l.origin.end());
      }
  }
  if (o.keep_light_ids) attributes->light.resize(n);
  if (o.keep_origins) attributes->origin.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (o.keep_light_ids) attributes->light[i] = in_order->light[original[i]];
    if (o.keep_origins) attributes->origin[i] = in_order->origin[original[i]];
  }
  return map;
}

// Fills `maps` (its global, direct and caustic maps and their stats.stored_* and build_seconds)
// as `o` says (AssemblePhotonMaps, photon_chunk.h).
void FillPhotonMaps(const PhotonMapsOptions& o, std::span<const PhotonChunk> chunks, PhotonMaps* maps) {
  const auto fill = [&](std::initializer_list<PhotonKind> kinds, PhotonAttributes* attributes) {
    return FillFromChunks(o, chunks, kinds, attributes);
  };
  std::array<uint64_t, 3> counts{};
  for (const PhotonChunk& c : chunks)
    for (size_t k = 0; k < 3; ++k) counts[k] += c.lists[k].photons.size();
  const auto t0 = std::chrono::steady_clock::now();
  if (o.separate_direct) {
    // Two independent maps: built concurrently, so that the serial top split of one kd-tree
    // overlaps with the other's build (each map is the same as when built alone).
    tbb::task_arena arena(o.tracing.threads > 0 ? o.tracing.threads : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_invoke([&] { maps->global = fill({PhotonKind::kIndirect}, &maps->global_attributes); },
                           [&] {
                             if (o.direct_map)
                               maps->direct = fill({PhotonKind::kDirect}, &maps->direct_attributes);
                           });
    });
  } else {
    maps->global = fill({PhotonKind::kDirect, PhotonKind::kIndirect}, &maps->global_attributes);
  }
  const uint64_t caustic_photons = counts[size_t(PhotonKind::kCaustic)];
  if (o.caustic == CausticMapMode::kOn) {
    maps->caustic = fill({PhotonKind::kCaustic}, &maps->caustic_attributes);
  } else if (caustic_photons > 0) {
    // Cannot happen in kAuto (no singular surface → no caustic photon); with kOff the caustic
    // photons are dropped on purpose and their light is missing from the image.
    spdlog::warn("photon maps: caustic map disabled: {} caustic photons dropped", caustic_photons);
  }
  maps->stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  maps->stats.stored_global = maps->global->size();
  maps->stats.stored_caustic = maps->caustic ? maps->caustic->size() : 0;
  maps->stats.stored_direct = maps->direct ? counts[size_t(PhotonKind::kDirect)] : 0;
}

}  // namespace

PhotonChunk TracePhotonChunk(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options, uint64_t begin, uint64_t end) {
  const auto start = std::chrono::steady_clock::now();
  PhotonTracerOptions to = options.tracing;
  to.photon_begin = begin;
  to.photon_end = end;
  if (end <= begin) throw std::invalid_argument("TracePhotonChunk: empty range");
  PhotonTracingResult traced = TracePhotons(scene, lights, to);
  PhotonChunk chunk;
  chunk.begin = begin;
  chunk.end = end;
  chunk.rays = traced.rays;
  chunk.emitted_power = traced.emitted_power;
  const uint64_t stored = traced.direct.size() + traced.indirect.size() + traced.caustic.size();
  chunk.counts = {traced.emitted, stored, traced.rejected, traced.chains, traced.mutations, traced.accepted};
  chunk.light_ids = options.keep_light_ids;
  chunk.origins = options.keep_origins;
  // Σ Φ in double, list by list in photon order: PhotonTracingResult::StoredPower's sum.
  for (const TracedPhotons* list : {&traced.direct, &traced.indirect, &traced.caustic})
    for (const TracedPhoton& p : *list) {
      chunk.stored_power[0] += p.power.r;
      chunk.stored_power[1] += p.power.g;
      chunk.stored_power[2] += p.power.b;
    }
  // Direct photons that no map will hold (PhotonMapsOptions::direct_map) do not travel; their
  // power counts in stored_power above, as for every stored photon.
  const bool drop_direct = options.separate_direct && !options.direct_map;
  const std::array<TracedPhotons*, 3> from = {&traced.direct, &traced.indirect, &traced.caustic};
  tbb::task_arena arena(to.threads > 0 ? to.threads : tbb::task_arena::automatic);
  for (size_t k = 0; k < 3; ++k) {
    TracedPhotons& l = *from[k];
    PhotonChunk::List& list = chunk.lists[k];
    if (!(drop_direct && k == size_t(PhotonKind::kDirect))) {
      // Compressing to 18 bytes (two arc functions and a frexp per photon) is independent per
      // photon: done in parallel into place (the same bytes as one by one).
      list.photons.resize(l.size());
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, l.size(), 16384), [&](const auto& range) {
          for (size_t i = range.begin(); i != range.end(); ++i)
            list.photons[i] = Photon::Make(l[i].position, l[i].direction, l[i].power);
        });
      });
      if (chunk.light_ids) list.light.reserve(l.size());
      if (chunk.origins) list.origin.reserve(l.size());
      for (const TracedPhoton& p : l) {
        if (chunk.light_ids) list.light.push_back(p.light);
        if (chunk.origins) list.origin.push_back(p.origin);
      }
    }
    TracedPhotons().swap(l);  // peak memory: each full-precision list freed once compressed
  }
  chunk.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
  const PhotonChunk::Counts& n = chunk.counts;
  for (uint64_t v : {n.emitted, n.stored, n.rejected, n.chains, n.mutations, n.accepted}) w.Put<uint64_t>(v);
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
  PhotonChunk::Counts& counts = chunk.counts;
  for (uint64_t* v : {&counts.emitted, &counts.stored, &counts.rejected, &counts.chains, &counts.mutations,
                      &counts.accepted})
    *v = r.Get<uint64_t>();
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
  // S·N photons leave the lights with brute-force splitting (§4.6.1), none without lights.
  const uint64_t per_photon =
      options.tracing.caustic_split > 1 && options.tracing.caustic_split_method == CausticSplitMethod::kBrute
          ? options.tracing.caustic_split
          : 1;
  uint64_t next = 0;
  for (const PhotonChunk& c : chunks) {
    if (c.begin != next)
      throw InputError("photon chunks: photons [" + std::to_string(next) + ", " + std::to_string(c.begin) +
                       ") are missing");
    if ((options.keep_light_ids && !c.light_ids) || (options.keep_origins && !c.origins))
      throw InputError("photon chunks: a chunk lacks the light ids or origins the maps need");
    if (c.counts.emitted != 0 && c.counts.emitted != (c.end - c.begin) * per_photon)
      throw InputError("photon chunks: photons [" + std::to_string(c.begin) + ", " + std::to_string(c.end) +
                       ") say " + std::to_string(c.counts.emitted) + " photons were emitted");
    next = c.end;
  }
  if (next != options.tracing.photons)
    throw InputError("photon chunks: cover " + std::to_string(next) + " of " +
                     std::to_string(options.tracing.photons) + " photons");
  PhotonMaps maps;
  maps.seed = options.tracing.map_seed;
  PhotonMapsStats& st = maps.stats;
  double power[3] = {0, 0, 0};
  for (const PhotonChunk& c : chunks) {
    st.emitted += c.counts.emitted;
    st.rays += c.rays;
    st.rejected += c.counts.rejected;
    st.chains += c.counts.chains;
    st.mutations += c.counts.mutations;
    st.accepted += c.counts.accepted;
    st.trace_seconds += c.seconds;
    for (int i = 0; i < 3; ++i) power[i] += c.stored_power[i];
  }
  st.stored_power = Rgb(float(power[0]), float(power[1]), float(power[2]));
  if (!chunks.empty()) st.emitted_power = chunks.front().emitted_power;
  FillPhotonMaps(options, chunks, &maps);
  return maps;
}

}  // namespace pf
