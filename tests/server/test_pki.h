// Certificates for TLS tests, made by the openssl CLI at test time (nothing secret is committed):
// in `dir`, ca.pem/ca.key (a CA), server.pem/server.key (CN localhost, SAN localhost and
// 127.0.0.1, signed by the CA), client.pem/client.key (signed by the CA) and other_ca.pem (a CA
// that signed nothing here).
#pragma once

#include <cstdlib>
#include <string>

namespace bgkmap::testing {

// True when every file was made.
inline bool MakeTestPki(const std::string& dir) {
  const std::string script =
      "set -e; cd '" + dir +
      "'; q() { \"$@\" >/dev/null 2>&1; }\n"
      "q openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days 2 "
      "-subj '/CN=bgkmap test CA'\n"
      "q openssl req -x509 -newkey rsa:2048 -nodes -keyout other_ca.key -out other_ca.pem "
      "-days 2 -subj '/CN=another CA'\n"
      "q openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr "
      "-subj '/CN=localhost'\n"
      "printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\\n' > san.ext\n"
      "q openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
      "-out server.pem -days 2 -extfile san.ext\n"
      "q openssl req -newkey rsa:2048 -nodes -keyout client.key -out client.csr "
      "-subj '/CN=robot-1'\n"
      "q openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
      "-out client.pem -days 2\n";
  return std::system(("bash -c \"$(cat <<'EOS'\n" + script + "EOS\n)\"").c_str()) == 0;
}

}  // namespace bgkmap::testing
