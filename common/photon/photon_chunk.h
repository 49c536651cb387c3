#pragma once
// A map traced in pieces (docs/farm.md, "Photon maps traced once"; distributed photon tracing): photons
// [begin, end) of one map, traced by any worker, travel to the coordinator in the compact 18-byte form (Wald
// 1999, §2.2) with only the per-photon attributes the estimators need; the coordinator concatenates the
// pieces in photon order and builds the maps once.
//
// Why the result equals a one-process PhotonMaps::Build: photon i draws from its own sample
// streams (photon_tracer.h), pieces start at multiples of kPhotonTracingChunk, so each of the
// direct / indirect / caustic lists of the pieces concatenated in order is the list a whole trace
// gives; the 18-byte compression is per photon; the maps are then filled and built exactly as
// Build fills them, by the same code (photon_maps_fill.h; tests/common/photon_chunk_test.cpp checks
// the bytes of both).
//
// Byte form of a piece (little endian), version 1:
//   "PFCHNK\r\n" u32 version  u64 begin, end, rays  f64 stored power r, g, b  f32 emitted power r, g, b
//   u8 has light ids, u8 has origins, u16 0
//   per list (direct, indirect, caustic): u64 N, N × 18 photon bytes, [N × u32 light],
//   [N × 3 f32 origin]
// (no digest: the transfer carries its checksums, docs/farm.md).

#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/photon/photon_maps.h"

namespace pf {

struct PhotonChunk {
  uint64_t begin = 0, end = 0;  // photon indices of the map
  uint64_t rays = 0;
  std::array<double, 3> stored_power{};  // Σ Φ of the stored photons, full precision
  Rgb emitted_power;                     // the lights' total power (the whole map's)
  bool light_ids = false, origins = false;
  struct List {
    std::vector<Photon> photons;
    std::vector<uint32_t> light;  // light_ids only
    std::vector<Vec3> origin;     // origins only
  };
  std::array<List, 3> lists;  // indexed by PhotonKind: direct, indirect, caustic
};

// Traces photons [begin, end) of the map `options` describes (options.tracing.photons is the
// whole map's count; begin a multiple of kPhotonTracingChunk).
PhotonChunk TracePhotonChunk(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options, uint64_t begin, uint64_t end);

std::string SerializePhotonChunk(const PhotonChunk& chunk);
// Throws InputError for malformed bytes.
PhotonChunk DeserializePhotonChunk(std::string_view bytes);

// The maps of `options` from pieces that cover [0, options.tracing.photons) in order (else
// InputError naming the gap). options.caustic must be resolved (kOn or kOff: std::logic_error
// for kAuto; JobRenderSettings::Resolved does it). stats.trace_seconds is 0 (the pieces' time is
// the workers'); stored_power is summed per piece (equal to Build's up to float rounding).
PhotonMaps AssemblePhotonMaps(std::span<const PhotonChunk> chunks, const PhotonMapsOptions& options);

}  // namespace pf
