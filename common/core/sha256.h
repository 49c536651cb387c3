#pragma once
// SHA-256 (OpenSSL EVP) for content addresses and transfer checksums of binary artifacts
// (photon maps and their chunks, docs/farm.md "Photon maps on the wire") and scene bundle hashes
// (scene_bundle.cpp, whose byte layout is documented there).

#include <memory>
#include <string>
#include <string_view>

namespace pf {

class Sha256Hasher {
 public:
  Sha256Hasher();
  ~Sha256Hasher();
  Sha256Hasher(const Sha256Hasher&) = delete;
  Sha256Hasher& operator=(const Sha256Hasher&) = delete;
  void Update(std::string_view bytes);
  // Lowercase hex of the 32-byte digest; the hasher is spent afterwards.
  std::string HexDigest();

 private:
  struct Context;
  std::unique_ptr<Context> ctx_;
};

// Lowercase hex SHA-256 of `bytes`. Throws SystemError if OpenSSL fails.
std::string Sha256Hex(std::string_view bytes);

}  // namespace pf
