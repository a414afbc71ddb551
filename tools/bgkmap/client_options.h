// Parsing shared by the subcommands that talk to bgkmapd: the server address, boxes, layers,
// and the one-line failure convention.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/core/status.h"

namespace bgkmap::cli {

inline constexpr const char* kDefaultServer = "127.0.0.1:50051";

// Where bgkmapd is and how to reach it: its address, TLS files and the bearer token's file.
struct ServerTarget {
  std::string address;
  std::string tls_ca;    // --tls-ca: CA certificates (PEM) the server must chain to
  std::string tls_cert;  // --tls-cert / --tls-key: this client's certificate (mTLS)
  std::string tls_key;
  std::string tls_server_name;  // --tls-server-name: the name the certificate carries
  std::string token_file;       // --token-file; else $BGKMAP_TOKEN holds the token itself
  bool float32_points = false;  // --float32 (insert): packed float32, not the compact encoding
};

// Adds --server (host:port of bgkmapd; default $BGKMAP_SERVER, else kDefaultServer), --tls-ca,
// --tls-cert, --tls-key, --tls-server-name and --token-file to `cmd`.
void AddServerOption(CLI::App* cmd, ServerTarget& server);

// The client for `target`, its files read; the error names the option at fault.
Result<std::unique_ptr<Client>> Connect(const ServerTarget& target);

// "xmin,ymin,xmax,ymax" already split by CLI11 into 4 numbers.
Result<MetricBox> ParseBox(const std::vector<double>& v, const std::string& option);

// Layer names ("elevation,state"); empty gives `fallback`.
Result<std::vector<Layer>> ParseLayers(const std::vector<std::string>& names,
                                       const std::vector<Layer>& fallback);

// Prints "bgkmap <command>: <message>" to stderr; returns kExitFailure (1).
int Fail(const std::string& command, const std::string& message);
// The same for a bad command line; returns kExitUsage (2).
int Usage(const std::string& command, const std::string& message);

// The GeoTIFF band contract shared by `bgkmap build` and `bgkmap query`.
const std::vector<Layer>& GeoTiffBands();

}  // namespace bgkmap::cli
