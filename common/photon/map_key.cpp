#include "common/photon/map_key.h"

#include <algorithm>

#include "common/core/sha256.h"

namespace pf {

std::string MapKey::Text() const {
  return scene + "|" + fingerprint + "|" + std::to_string(seed);
}

std::string MapKey::Address(std::string_view build) const {
  // The text of the first format of this address: the files a coordinator stored before keep
  // their names.
  std::string text = "photonfarm-map-v1\n" + std::string(build) + "\n" + scene + "\n";
  text += fingerprint;
  text += '\n';
  text += std::to_string(seed);
  return Sha256Hex(text);
}

bool MapKey::IsAddress(std::string_view text) {
  return text.size() == 64 && std::all_of(text.begin(), text.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

}  // namespace pf
