#pragma once
// The photon as the tracer produces it (Wald 1999, §2.2), in full precision, and the arrays it is
// appended to; the maps compress each to the 18-byte Photon (photon.h) when they are built.

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/core/math.h"

namespace pf {

enum class PhotonKind : uint8_t { kDirect = 0, kIndirect = 1, kCaustic = 2 };

// Full-precision photon as traced; compressed to the 18-byte Photon when put in a map.
struct TracedPhoton {
  Vec3 position;
  Vec3 direction;  // unit, pointing back towards where the photon came from (ω in §2.2)
  Rgb power;       // Φ, W
  // The previous vertex of the path (occlusion testing, §4.1.1), as the ray that left it started:
  // moved off its surface to the side the photon left on (OffsetRayOrigin). A test ray from a point
  // that sees that side ends short of the surface; one from behind a zero-thickness wall crosses it.
  Vec3 origin;
  uint32_t light = 0;  // emitting light id (PhotonDirect, §4.2.3)
  PhotonKind kind = PhotonKind::kIndirect;
  // Explicit, zero-initialised padding: arrays of equal photons are equal byte for byte however
  // each photon was made (aggregate, copy or AppendPhoton), so tests can compare them with memcmp.
  uint8_t pad[3] = {};
};

// An allocator whose value-initialising construct() does nothing, for arrays that are sized
// first and then filled in parallel: std::vector::resize would otherwise zero them in one serial
// pass (~35 ms for the 1.5M photons of the default map, 7 % of its 1-thread tracing time, which
// alone would cap two threads at 1.87x). Only for implicit-lifetime, trivially copyable types,
// whose objects the copy that fills the memory creates.
template <typename T>
struct UninitializedAllocator : std::allocator<T> {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);
  template <typename U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <typename U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U*) noexcept {}
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

using TracedPhotons = std::vector<TracedPhoton, UninitializedAllocator<TracedPhoton>>;

// Appends a traced photon (§2.2) by writing its fields straight into the array's memory
// (UninitializedAllocator: emplace_back() leaves it unwritten) instead of copying a temporary
// built on the stack: the copy's 16-byte loads of the temporary's 12- and 4-byte stores stalled
// on store forwarding at every stored photon (docs/results/kernel.md §4). The light id, the kind
// and the 3 bytes of TracedPhoton::pad are one 8-byte store, the pad zero as in every other
// TracedPhoton, so that equal arrays are equal byte for byte (the tracer's memcmp test).
static_assert(offsetof(TracedPhoton, kind) == offsetof(TracedPhoton, light) + 4 &&
              sizeof(TracedPhoton) == offsetof(TracedPhoton, light) + 8 &&
              std::endian::native == std::endian::little);
inline void AppendPhoton(TracedPhotons& list, const Vec3& position, const Vec3& direction, const Rgb& power,
                         const Vec3& origin, uint32_t light, PhotonKind kind) {
  TracedPhoton& p = list.emplace_back();
  p.position = position;
  p.direction = direction;
  p.power = power;
  p.origin = origin;
  const uint64_t tail = uint64_t(light) | uint64_t(kind) << 32;
  std::memcpy(reinterpret_cast<unsigned char*>(&p) + offsetof(TracedPhoton, light), &tail, sizeof tail);
}

}  // namespace pf
