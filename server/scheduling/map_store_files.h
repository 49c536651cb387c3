#pragma once
// The files of the coordinator's map store (<data-dir>/maps, distributed_maps.h): a built map is
// <key>.pfmaps (common/photon/photon_maps_bytes.h), its pieces <key>.chunks/BEGIN-END, and beside
// each file the record of who traced it (<file>.by, one worker id a line: a conviction deletes
// what a convicted worker traced).

#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>

namespace pf::server {

inline constexpr std::string_view kMapFileSuffix = ".pfmaps";

inline std::filesystem::path MapFileOf(const std::filesystem::path& dir, const std::string& key) {
  return dir / (key + std::string(kMapFileSuffix));
}

// A key as logs show it.
inline std::string ShortKey(const std::string& key) {
  return key.substr(0, 12);
}

inline std::filesystem::path TracersFile(const std::filesystem::path& file) {
  return std::filesystem::path(file.string() + ".by");
}

inline void RemoveWithTracers(const std::filesystem::path& file) {
  std::error_code ec;
  std::filesystem::remove(file, ec);
  std::filesystem::remove(TracersFile(file), ec);
}

}  // namespace pf::server
