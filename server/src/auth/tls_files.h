// The PEM files of server.tls, read and checked once at start: a certificate that does not parse
// or a key that does not match it fails the start with the key's name, instead of a handshake
// error on the first connection. Both listeners (gRPC and HTTP) serve the same material.
#pragma once

#include <string>

#include "bgkmap/core/status.h"
#include "bgkmap/server/server_config.h"

namespace bgkmap {

struct TlsMaterial {
  std::string cert_chain_pem;   // server.tls.cert_file
  std::string private_key_pem;  // server.tls.key_file
  std::string client_ca_pem;    // server.tls.client_ca_file; "" = no client certificates asked
};

// Reads and checks the files of `tls` (which must be enabled). Errors start with the key
// ("server.tls.key_file: '/etc/k.pem': does not match server.tls.cert_file").
Result<TlsMaterial> LoadTlsMaterial(const TlsConfig& tls);

}  // namespace bgkmap
