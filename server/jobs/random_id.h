#pragma once
// Unguessable, never-reused identifiers from OpenSSL's CSPRNG (RAND_bytes). Job ids carry 128
// random bits so that an id is never handed out twice, even when the job table is lost (a
// restored or deleted SQLite file restarts the sequence counter; an old journal or checkpoint
// must not be replayed into a new job that got its id). Lease ids carry 128 random bits so that
// a worker cannot guess another worker's lease (docs/security.md).

#include <cstddef>
#include <string>

namespace pf::server {

// 2 × `bytes` lowercase hex characters of cryptographic randomness. SystemError if the CSPRNG
// fails.
std::string RandomHex(size_t bytes);

}  // namespace pf::server
