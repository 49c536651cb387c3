#pragma once
// PhotonMaps as bytes: the versioned form in which a map built once travels to the workers and
// sits in their disk caches (docs/farm.md "Photon maps on the wire").
//
// A left-balanced kd-tree *is* its photon array in heap order (Wald 1999, §2.3), so what is
// written is each built map's 18-byte photon array as it is after the build, plus the 2-bit
// split axes of a widest-extent tree and the per-photon attributes an estimator asked for (light
// ids, §4.2.3; origins, §4.1.1). Reading it back builds nothing: the maps answer every query
// bit for bit as the ones written (tests/common/photon_maps_bytes_test.cpp).
//
// Layout (little endian, byte_codec.h), format version 1:
//   "PFMAPS\r\n"  u32 version  u64 seed
//   stats: u64 emitted, stored_global, stored_caustic, stored_direct, rays; f64 trace_seconds,
//          build_seconds; f32 emitted_power[3], stored_power[3]
//   u32 present: bit 0 global, bit 1 caustic, bit 2 direct
//   per present map, in that order:
//     u8 split rule (KdSplitRule), u8 culling (KdCulling), u16 0
//     u64 photons N, u64 axis bytes A, u8 has light ids, u8 has origins, u16 0, u32 0
//     N × 18 photon bytes, A axis bytes, [N × u32 light], [N × 3 f32 origin]
//   32 bytes: SHA-256 of everything before it
// Only kd-tree maps have this form (the grid and the bucketed kd-tree keep side structures
// that are not part of their photon array): CanSerialize says which maps can travel.
//
// Reading never trusts the input: every count is checked against the bytes left and the limits
// of PhotonMap, the digest against the content; truncated or corrupt input throws InputError
// ("photon maps: truncated", "photon maps: digest mismatch", ...), never reads out of bounds.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "common/photon/photon_maps.h"

namespace pf {

inline constexpr uint32_t kPhotonMapsBytesVersion = 1;

// Whether every map of `maps` is a kd-tree (the only structure with a byte form).
bool CanSerialize(const PhotonMaps& maps);
bool CanSerialize(PhotonMapKind kind);

// Throws std::logic_error if !CanSerialize(maps).
std::string SerializePhotonMaps(const PhotonMaps& maps);
// Throws InputError for anything but the exact bytes SerializePhotonMaps wrote.
PhotonMaps DeserializePhotonMaps(std::string_view bytes);

// The one reader of the trailer: the digest the bytes record (lowercase hex SHA-256 of the
// content, the MapRef.digest that names a map), read, not verified (DeserializePhotonMaps verifies
// it). InputError if the bytes are too short to have one.
std::string PhotonMapsDigest(std::string_view bytes);
// The same from a file, reading only its trailer (InputError if too short, SystemError if
// unreadable).
std::string PhotonMapsFileDigest(const std::filesystem::path& file);
// The maps the coordinator named by `digest` for `seed`: nullopt if the bytes' trailer is another
// digest (checked before anything is parsed) or the maps are of another seed; InputError if the
// bytes are corrupt.
std::optional<PhotonMaps> ReadNamedPhotonMaps(std::string_view bytes, std::string_view digest, uint64_t seed);

}  // namespace pf
