// TLS for the HTTP endpoint: the Boost.Asio SSL context built from server.tls (the same
// certificate and key as the gRPC port; client certificates required when client_ca_file is set).
#pragma once

#include <boost/asio/ssl/context.hpp>
#include <memory>

#include "auth/tls_files.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

Result<std::shared_ptr<boost::asio::ssl::context>> MakeHttpsContext(const TlsMaterial& tls);

}  // namespace bgkmap
