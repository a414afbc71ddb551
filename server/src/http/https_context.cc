#include "http/https_context.h"

#include <openssl/ssl.h>

#include <boost/asio/buffer.hpp>
#include <boost/system/system_error.hpp>

namespace bgkmap {

Result<std::shared_ptr<boost::asio::ssl::context>> MakeHttpsContext(const TlsMaterial& tls) {
  namespace ssl = boost::asio::ssl;
  auto ctx = std::make_shared<ssl::context>(ssl::context::tls_server);
  boost::system::error_code ec;
  ctx->set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 |
                       ssl::context::no_sslv3 | ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1 |
                       ssl::context::single_dh_use,
                   ec);
  // TLS 1.2: forward secrecy (ECDHE) and AEAD only; TLS 1.3's suites all have both. The list
  // of docs/server.md, Security (issue 25: plain RSA key exchange was offered).
  if (!ec &&
      SSL_CTX_set_cipher_list(ctx->native_handle(),
                              "ECDHE-ECDSA-AES128-GCM-SHA256:ECDHE-RSA-AES128-GCM-SHA256:"
                              "ECDHE-ECDSA-AES256-GCM-SHA384:ECDHE-RSA-AES256-GCM-SHA384:"
                              "ECDHE-ECDSA-CHACHA20-POLY1305:ECDHE-RSA-CHACHA20-POLY1305") != 1) {
    return Status::InvalidArgument("server.tls: HTTP endpoint: no usable cipher");
  }
  if (!ec) ctx->use_certificate_chain(boost::asio::buffer(tls.cert_chain_pem), ec);
  if (!ec) ctx->use_private_key(boost::asio::buffer(tls.private_key_pem), ssl::context::pem, ec);
  if (!ec && !tls.client_ca_pem.empty()) {
    ctx->add_certificate_authority(boost::asio::buffer(tls.client_ca_pem), ec);
    if (!ec) ctx->set_verify_mode(ssl::verify_peer | ssl::verify_fail_if_no_peer_cert, ec);
  }
  if (ec) return Status::InvalidArgument("server.tls: HTTP endpoint: " + ec.message());
  return ctx;
}

}  // namespace bgkmap
