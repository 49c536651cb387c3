#include "common/photon/photon_maps_bytes.h"

#include <cstring>
#include <fstream>
#include <stdexcept>

#include "common/core/byte_codec.h"
#include "common/core/sha256.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon_map_factory.h"

namespace pf {
namespace {

constexpr std::string_view kMagic = "PFMAPS\r\n";
constexpr size_t kDigestBytes = 32;
constexpr char kHexDigits[] = "0123456789abcdef";

std::string HexOf(std::string_view raw) {
  std::string hex;
  for (unsigned char c : raw) {
    hex.push_back(kHexDigits[c >> 4]);
    hex.push_back(kHexDigits[c & 15]);
  }
  return hex;
}

void PutMap(ByteWriter& w, const PhotonMap& map, const PhotonAttributes& attributes) {
  const auto* tree = dynamic_cast<const KdTree*>(&map);
  if (!tree) throw std::logic_error("SerializePhotonMaps: only kd-tree maps have a byte form");
  if (!map.prepared()) throw std::logic_error("SerializePhotonMaps: the map is not built");
  w.Put<uint8_t>(uint8_t(tree->split_rule()));
  w.Put<uint8_t>(uint8_t(tree->culling()));
  w.Put<uint16_t>(0);
  const uint64_t n = map.size();
  w.Put<uint64_t>(n);
  w.Put<uint64_t>(tree->stored_axes().size());
  const bool lights = !attributes.light.empty(), origins = !attributes.origin.empty();
  if ((lights && attributes.light.size() != n) || (origins && attributes.origin.size() != n))
    throw std::logic_error("SerializePhotonMaps: attributes do not match the photons");
  w.Put<uint8_t>(lights);
  w.Put<uint8_t>(origins);
  w.Put<uint16_t>(0);
  w.Put<uint32_t>(0);
  const std::span<const Photon> photons = map.photons();
  w.PutBytes(std::string_view(reinterpret_cast<const char*>(photons.data()), photons.size_bytes()));
  w.PutArray<uint8_t>(tree->stored_axes());
  if (lights) w.PutArray<uint32_t>(attributes.light);
  if (origins)
    for (const Vec3& o : attributes.origin) {
      w.Put<float>(o.x);
      w.Put<float>(o.y);
      w.Put<float>(o.z);
    }
}

std::unique_ptr<PhotonMap> GetMap(ByteReader& r, PhotonAttributes* attributes) {
  const uint8_t rule = r.Get<uint8_t>(), culling = r.Get<uint8_t>();
  if (rule > uint8_t(KdSplitRule::kWidestExtent)) r.Fail("unknown kd split rule " + std::to_string(rule));
  if (culling > uint8_t(KdCulling::kCellDistance)) r.Fail("unknown kd culling " + std::to_string(culling));
  if (r.Get<uint16_t>() != 0) r.Fail("reserved bytes are not zero");
  const uint64_t n = r.Get<uint64_t>(), axes = r.Get<uint64_t>();
  const uint8_t lights = r.Get<uint8_t>(), origins = r.Get<uint8_t>();
  if (lights > 1 || origins > 1 || r.Get<uint16_t>() != 0 || r.Get<uint32_t>() != 0)
    r.Fail("malformed map header");
  if (n > PhotonMap::kMaxPhotons) r.Fail(std::to_string(n) + " photons exceed the limit");
  // Checked before allocating: a corrupt count must not allocate what the bytes cannot hold.
  const uint64_t need = n * (sizeof(Photon) + 4 * lights + 12 * origins) + axes;
  if (need > r.remaining()) r.Fail("truncated");
  std::vector<Photon> photons(n);
  const std::string_view bytes = r.GetBytes(n * sizeof(Photon));
  if (n > 0) std::memcpy(photons.data(), bytes.data(), bytes.size());
  std::vector<uint8_t> axis_bytes(axes);
  r.GetArray<uint8_t>(axis_bytes);
  if (lights) {
    attributes->light.resize(n);
    r.GetArray<uint32_t>(attributes->light);
  }
  if (origins) {
    attributes->origin.resize(n);
    for (Vec3& o : attributes->origin) {
      o.x = r.Get<float>();
      o.y = r.Get<float>();
      o.z = r.Get<float>();
    }
  }
  try {
    return KdTree::FromBalanced(KdSplitRule(rule), KdCulling(culling), std::move(photons),
                                std::move(axis_bytes));
  } catch (const std::invalid_argument& e) {
    r.Fail(e.what());
  }
}

}  // namespace

bool CanSerialize(PhotonMapKind kind) {
  return PhotonMapStructures().FindKind(kind).serializable;
}

bool CanSerialize(const PhotonMaps& maps) {
  for (const PhotonMap* m : {maps.global.get(), maps.caustic.get(), maps.direct.get()})
    if (m && !dynamic_cast<const KdTree*>(m)) return false;
  return maps.global != nullptr;
}

std::string SerializePhotonMaps(const PhotonMaps& maps) {
  if (!CanSerialize(maps)) throw std::logic_error("SerializePhotonMaps: only kd-tree maps have a byte form");
  std::string out;
  size_t photons = 0;
  for (const PhotonMap* m : {maps.global.get(), maps.caustic.get(), maps.direct.get()})
    if (m) photons += m->size();
  out.reserve(256 + photons * (sizeof(Photon) + 16) + kDigestBytes);
  ByteWriter w(out);
  w.PutBytes(kMagic);
  w.Put<uint32_t>(kPhotonMapsBytesVersion);
  w.Put<uint64_t>(maps.seed);
  const PhotonMapsStats& s = maps.stats;
  for (uint64_t v : {s.emitted, s.stored_global, s.stored_caustic, s.stored_direct, s.rays})
    w.Put<uint64_t>(v);
  w.Put<double>(s.trace_seconds);
  w.Put<double>(s.build_seconds);
  for (const Rgb& c : {s.emitted_power, s.stored_power}) {
    w.Put<float>(c.r);
    w.Put<float>(c.g);
    w.Put<float>(c.b);
  }
  const uint32_t present = (maps.global ? 1u : 0u) | (maps.caustic ? 2u : 0u) | (maps.direct ? 4u : 0u);
  w.Put<uint32_t>(present);
  if (maps.global) PutMap(w, *maps.global, maps.global_attributes);
  if (maps.caustic) PutMap(w, *maps.caustic, maps.caustic_attributes);
  if (maps.direct) PutMap(w, *maps.direct, maps.direct_attributes);
  const std::string hex = Sha256Hex(out);
  for (size_t i = 0; i < kDigestBytes; ++i) out.push_back(char(std::stoi(hex.substr(2 * i, 2), nullptr, 16)));
  return out;
}

PhotonMaps DeserializePhotonMaps(std::string_view bytes) {
  if (bytes.size() < kMagic.size() + 4 + kDigestBytes) throw InputError("photon maps: truncated");
  if (bytes.substr(0, kMagic.size()) != kMagic)
    throw InputError("photon maps: not a photon map file (bad magic)");
  const std::string_view body = bytes.substr(0, bytes.size() - kDigestBytes);
  {
    ByteReader header(bytes.substr(kMagic.size()), "photon maps");
    const uint32_t version = header.Get<uint32_t>();
    if (version != kPhotonMapsBytesVersion)
      throw InputError("photon maps: format version " + std::to_string(version) + " (this build reads " +
                       std::to_string(kPhotonMapsBytesVersion) + ")");
  }
  if (Sha256Hex(body) != PhotonMapsDigest(bytes))
    throw InputError("photon maps: digest mismatch (corrupt or truncated)");
  ByteReader r(body.substr(kMagic.size() + 4), "photon maps");
  PhotonMaps maps;
  maps.seed = r.Get<uint64_t>();
  PhotonMapsStats& s = maps.stats;
  for (uint64_t* v : {&s.emitted, &s.stored_global, &s.stored_caustic, &s.stored_direct, &s.rays})
    *v = r.Get<uint64_t>();
  s.trace_seconds = r.Get<double>();
  s.build_seconds = r.Get<double>();
  for (Rgb* c : {&s.emitted_power, &s.stored_power}) {
    c->r = r.Get<float>();
    c->g = r.Get<float>();
    c->b = r.Get<float>();
  }
  const uint32_t present = r.Get<uint32_t>();
  if (!(present & 1u) || present > 7u) r.Fail("malformed map list " + std::to_string(present));
  maps.global = GetMap(r, &maps.global_attributes);
  if (present & 2u) maps.caustic = GetMap(r, &maps.caustic_attributes);
  if (present & 4u) maps.direct = GetMap(r, &maps.direct_attributes);
  if (!r.empty()) r.Fail(std::to_string(r.remaining()) + " bytes after the last map");
  return maps;
}

std::string PhotonMapsDigest(std::string_view bytes) {
  if (bytes.size() < kDigestBytes) throw InputError("photon maps: truncated (no digest)");
  return HexOf(bytes.substr(bytes.size() - kDigestBytes));
}

std::string PhotonMapsFileDigest(const std::filesystem::path& file) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(file, ec);
  if (ec) throw SystemError(file.string() + ": cannot read");
  if (size < kDigestBytes) throw InputError(file.string() + ": too short for a photon map");
  std::ifstream in(file, std::ios::binary);
  in.seekg(std::streamoff(size - kDigestBytes));
  std::string raw(kDigestBytes, '\0');
  in.read(raw.data(), std::streamsize(kDigestBytes));
  if (!in) throw SystemError(file.string() + ": cannot read");
  return HexOf(raw);
}

std::optional<PhotonMaps> ReadNamedPhotonMaps(std::string_view bytes, std::string_view digest,
                                              uint64_t seed) {
  if (bytes.size() < kDigestBytes || digest.size() != 2 * kDigestBytes || PhotonMapsDigest(bytes) != digest)
    return std::nullopt;
  PhotonMaps maps = DeserializePhotonMaps(bytes);  // verifies the digest against the content
  if (maps.seed != seed) return std::nullopt;
  return maps;
}

}  // namespace pf
