#pragma once
// Owning pointers to OpenSSL objects, and reading PEM text into them: shared by the diagnostic
// handshake (rpc/tls_diagnosis.cpp) and the status page's TLS (server/http/http_gate.cpp). A
// target that includes this links OpenSSL::SSL itself (pf_rpc links it privately).

#include <openssl/bio.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>

#include <memory>
#include <string_view>

namespace pf {

template <auto Free>
struct OpenSslFree {
  template <typename T>
  void operator()(T* p) const {
    Free(p);
  }
};

using SslCtxPtr = std::unique_ptr<SSL_CTX, OpenSslFree<SSL_CTX_free>>;
using SslPtr = std::unique_ptr<SSL, OpenSslFree<SSL_free>>;
using BioPtr = std::unique_ptr<BIO, OpenSslFree<BIO_free>>;
using X509Ptr = std::unique_ptr<X509, OpenSslFree<X509_free>>;
using PkeyPtr = std::unique_ptr<EVP_PKEY, OpenSslFree<EVP_PKEY_free>>;

// A read-only memory BIO over `pem` (which must outlive it); null if out of memory.
inline BioPtr MemoryBio(std::string_view pem) {
  return BioPtr(BIO_new_mem_buf(pem.data(), int(pem.size())));
}

// The next certificate in `bio`; null at the end (OpenSSL then queues "no start line": the caller
// clears it) or on an error.
inline X509Ptr ReadPemCertificate(BIO* bio) {
  return X509Ptr(PEM_read_bio_X509(bio, nullptr, nullptr, nullptr));
}

// The first private key in `bio`; null if there is none.
inline PkeyPtr ReadPemPrivateKey(BIO* bio) {
  return PkeyPtr(PEM_read_bio_PrivateKey(bio, nullptr, nullptr, nullptr));
}

}  // namespace pf
