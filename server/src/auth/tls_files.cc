#include "auth/tls_files.h"

#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>

namespace bgkmap {
namespace {

struct BioFree {
  void operator()(BIO* b) const { BIO_free(b); }
};
struct X509Free {
  void operator()(X509* x) const { X509_free(x); }
};
struct KeyFree {
  void operator()(EVP_PKEY* k) const { EVP_PKEY_free(k); }
};
using Bio = std::unique_ptr<BIO, BioFree>;
using Cert = std::unique_ptr<X509, X509Free>;
using Key = std::unique_ptr<EVP_PKEY, KeyFree>;

Result<std::string> ReadFile(const std::string& key, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Status::InvalidArgument("server." + key + ": '" + path +
                                   "': cannot read: " + std::strerror(errno));
  }
  std::stringstream text;
  text << in.rdbuf();
  if (text.str().empty()) {
    return Status::InvalidArgument("server." + key + ": '" + path + "': the file is empty");
  }
  return text.str();
}

Bio MemoryBio(const std::string& pem) {
  return Bio(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())));
}

// The certificates of a PEM bundle (0 if the first does not parse).
int CountCertificates(const std::string& pem, Cert* first) {
  Bio bio = MemoryBio(pem);
  int n = 0;
  while (Cert c{PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr)}) {
    if (n == 0 && first != nullptr) *first = std::move(c);
    ++n;
  }
  ERR_clear_error();  // the read past the last certificate
  return n;
}

}  // namespace

Result<TlsMaterial> LoadTlsMaterial(const TlsConfig& tls) {
  TlsMaterial m;
  Result<std::string> cert = ReadFile("tls.cert_file", tls.cert_file);
  if (!cert.ok()) return cert.status();
  Result<std::string> key = ReadFile("tls.key_file", tls.key_file);
  if (!key.ok()) return key.status();
  m.cert_chain_pem = std::move(cert).value();
  m.private_key_pem = std::move(key).value();
  Cert leaf;
  if (CountCertificates(m.cert_chain_pem, &leaf) == 0) {
    return Status::InvalidArgument("server.tls.cert_file: '" + tls.cert_file +
                                   "': no PEM certificate in it");
  }
  Bio key_bio = MemoryBio(m.private_key_pem);
  Key pkey{PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr)};
  ERR_clear_error();
  if (pkey == nullptr) {
    return Status::InvalidArgument("server.tls.key_file: '" + tls.key_file +
                                   "': no unencrypted PEM private key in it");
  }
  if (X509_check_private_key(leaf.get(), pkey.get()) != 1) {
    ERR_clear_error();
    return Status::InvalidArgument("server.tls.key_file: '" + tls.key_file +
                                   "': does not match the certificate of server.tls.cert_file");
  }
  if (!tls.client_ca_file.empty()) {
    Result<std::string> ca = ReadFile("tls.client_ca_file", tls.client_ca_file);
    if (!ca.ok()) return ca.status();
    m.client_ca_pem = std::move(ca).value();
    if (CountCertificates(m.client_ca_pem, nullptr) == 0) {
      return Status::InvalidArgument("server.tls.client_ca_file: '" + tls.client_ca_file +
                                     "': no PEM certificate in it");
    }
  }
  return m;
}

}  // namespace bgkmap
