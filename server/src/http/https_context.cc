#include "http/https_context.h"

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
