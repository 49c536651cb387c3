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
// A uniform double in [0, 1) with 53 bits from the CSPRNG (the choice of results to verify,
// docs/farm.md "Result verification": a worker cannot predict it). SystemError if it fails.
double RandomUnit();

}  // namespace pf::server
