#include "server/jobs/random_id.h"

#include <openssl/rand.h>

#include <cstdint>
#include <vector>

#include "common/core/error.h"

namespace pf::server {

std::string RandomHex(size_t bytes) {
  std::vector<unsigned char> raw(bytes);
  if (bytes > 0 && RAND_bytes(raw.data(), int(bytes)) != 1) throw SystemError("RAND_bytes failed");
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * bytes);
  for (const unsigned char b : raw) {
    hex.push_back(kHex[b >> 4]);
    hex.push_back(kHex[b & 15]);
  }
  return hex;
}

double RandomUnit() {
  unsigned char raw[8];
  if (RAND_bytes(raw, int(sizeof(raw))) != 1) throw SystemError("RAND_bytes failed");
  uint64_t bits = 0;
  for (const unsigned char b : raw) bits = (bits << 8) | b;
  return double(bits >> 11) * 0x1.0p-53;
}

}  // namespace pf::server
