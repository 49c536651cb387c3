#pragma once
// A map traced in pieces, and the one way every photon map is filled and built (docs/farm.md,
// "Photon maps traced once"; distributed photon tracing): photons [begin, end) of one map, traced
// by any worker or by the local process, are kept in the compact 18-byte form (Wald 1999, §2.2)
// with only the per-photon attributes the estimators need; AssemblePhotonMaps concatenates the
// pieces in photon order and builds the maps once. There is one build path: PhotonMaps::Build
// traces its own pieces [0, N) (photon_maps.h) and assembles them with the same AssemblePhotonMaps
// the coordinator calls on the workers' pieces.
//
// Why pieces equal a whole trace: photon i draws from its own sample streams (photon_tracer.h),
// pieces start at multiples of kPhotonTracingChunk, so each of the direct / indirect / caustic
// lists of the pieces concatenated in order is the list a whole trace gives, for any cuts; the
// 18-byte compression is per photon. That holds with importance-driven storing (§4.7: the
// acceptance test draws from the photon's own acceptance slot; the importance map is built once,
// before the pieces) and with caustic splitting (§4.6: brute force keeps one of photon i's S
// emissions by Rng(map seed, i); a Metropolis chain is mutated within its photon's walk). Only
// the float sum of the stored power depends on the cuts (summed per piece, then over pieces):
// see AssemblePhotonMaps. tests/common/photon_chunk_test.cpp checks the bytes of maps from
// several cuts against PhotonMaps::Build (one piece).
//
// Byte form of a piece (little endian), version 2:
//   "PFCHNK\r\n" u32 version  u64 begin, end, rays  f64 stored power r, g, b  f32 emitted power r, g, b
//   u64 emitted, stored, rejected, chains, mutations, accepted  (PhotonChunk::counts)
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
  // What the trace of the piece counted (PhotonTracingResult): photons that left the lights
  // ((end − begin)·S with brute-force splitting, 0 without lights), photons stored (the dropped
  // direct ones included), diffuse hits not stored by importance (§4.7), Metropolis chains
  // split, mutations tried and accepted (§4.6.2).
  struct Counts {
    uint64_t emitted = 0, stored = 0, rejected = 0, chains = 0, mutations = 0, accepted = 0;
  } counts;
  double seconds = 0;  // the trace and the compression; not in the byte form (a measurement)
  bool light_ids = false, origins = false;
  struct List {
    std::vector<Photon> photons;
    std::vector<uint32_t> light;  // light_ids only
    std::vector<Vec3> origin;     // origins only
  };
  std::array<List, 3> lists;  // indexed by PhotonKind: direct, indirect, caustic
};

// Traces photons [begin, end) of the map `options` describes (options.tracing.photons is the
// whole map's count; begin a multiple of kPhotonTracingChunk; options.tracing.importance, if
// set, is the map's importance map). Direct photons no map will hold (separate_direct without
// direct_map) are counted in stored_power and dropped.
PhotonChunk TracePhotonChunk(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options, uint64_t begin, uint64_t end);

std::string SerializePhotonChunk(const PhotonChunk& chunk);
// Throws InputError for malformed bytes.
PhotonChunk DeserializePhotonChunk(std::string_view bytes);

// The maps of `options` from pieces that cover [0, options.tracing.photons) in order (else
// InputError naming the gap), filled and built: the global map from the direct and indirect
// lists, or from the indirect list with separate_direct (then the direct map, if direct_map,
// concurrently); the caustic map if options.caustic is kOn (with kOff its photons are dropped,
// with a warning). options.caustic must be resolved (kOn or kOff: std::logic_error for kAuto;
// JobRenderSettings::Resolved and PhotonMaps::Build do it). stats: emitted, rays, rejected and
// stored_power summed over the pieces; stored_power is summed in double per piece and then over
// the pieces, so it is a whole trace's sum bit for bit for one piece and equal up to float
// rounding for other cuts (it is reported and stored in the map file, never read by an
// estimator). trace_seconds is the sum of the pieces' `seconds` (0 for pieces read from bytes:
// their time was the workers').
PhotonMaps AssemblePhotonMaps(std::span<const PhotonChunk> chunks, const PhotonMapsOptions& options);

}  // namespace pf
