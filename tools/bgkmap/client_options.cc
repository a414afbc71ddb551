#include "client_options.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <tuple>

#include "commands.h"

namespace bgkmap::cli {

void AddServerOption(CLI::App* cmd, ServerTarget& server) {
  server.address = kDefaultServer;
  cmd->add_option("--server", server.address, "bgkmapd address host:port")
      ->envname("BGKMAP_SERVER")
      ->capture_default_str();
  cmd->add_option("--tls-ca", server.tls_ca,
                  "Connect with TLS; the server certificate must chain to these CAs (PEM)");
  cmd->add_option("--tls-cert", server.tls_cert, "Client certificate for mutual TLS (PEM)");
  cmd->add_option("--tls-key", server.tls_key, "Private key of --tls-cert (PEM)");
  cmd->add_option("--tls-server-name", server.tls_server_name,
                  "Name the server certificate must carry (default: the --server host)");
  cmd->add_option("--token-file", server.token_file,
                  "File holding the bearer token (else $BGKMAP_TOKEN holds the token)");
}

namespace {

Result<std::string> ReadWhole(const std::string& option, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::InvalidArgument(option + ": cannot read '" + path + "'");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

Result<std::unique_ptr<Client>> Connect(const ServerTarget& target) {
  ClientOptions options;
  if (target.tls_cert.empty() != target.tls_key.empty()) {
    return Status::InvalidArgument("--tls-cert and --tls-key go together");
  }
  if (!target.tls_cert.empty() && target.tls_ca.empty()) {
    return Status::InvalidArgument("--tls-cert needs --tls-ca (client certificates need TLS)");
  }
  for (const auto& [option, path, out] : {std::tuple<const char*, const std::string&, std::string*>{
                                              "--tls-ca", target.tls_ca, &options.tls_ca_pem},
                                          {"--tls-cert", target.tls_cert, &options.tls_cert_pem},
                                          {"--tls-key", target.tls_key, &options.tls_key_pem}}) {
    if (path.empty()) continue;
    Result<std::string> pem = ReadWhole(option, path);
    if (!pem.ok()) return pem.status();
    *out = std::move(pem).value();
  }
  options.tls_server_name = target.tls_server_name;
  if (target.float32_points) options.compact_step = 0;
  if (!target.token_file.empty()) {
    Result<std::string> token = ReadWhole("--token-file", target.token_file);
    if (!token.ok()) return token.status();
    options.token = std::move(token).value();
  } else if (const char* env = std::getenv("BGKMAP_TOKEN")) {
    options.token = env;
  }
  // A token file ends with a newline, as `echo` writes it.
  while (!options.token.empty() && std::isspace(static_cast<unsigned char>(options.token.back()))) {
    options.token.pop_back();
  }
  return std::make_unique<Client>(target.address, options);
}

Result<MetricBox> ParseBox(const std::vector<double>& v, const std::string& option) {
  if (v.size() != 4) return Status::InvalidArgument(option + ": expected xmin,ymin,xmax,ymax");
  for (double x : v) {
    if (!std::isfinite(x)) return Status::InvalidArgument(option + ": coordinates must be finite");
  }
  if (!(v[0] < v[2]) || !(v[1] < v[3])) {
    return Status::InvalidArgument(option + ": need xmin < xmax and ymin < ymax");
  }
  return MetricBox{v[0], v[1], v[2], v[3]};
}

Result<std::vector<Layer>> ParseLayers(const std::vector<std::string>& names,
                                       const std::vector<Layer>& fallback) {
  if (names.empty()) return fallback;
  std::vector<Layer> layers;
  for (const std::string& n : names) {
    Result<Layer> l = ParseLayer(n);
    if (!l.ok()) return Status::InvalidArgument("--layers: " + l.status().message());
    layers.push_back(*l);
  }
  return layers;
}

int Fail(const std::string& command, const std::string& message) {
  std::fprintf(stderr, "bgkmap %s: %s\n", command.c_str(), message.c_str());
  return kExitFailure;
}

int Usage(const std::string& command, const std::string& message) {
  Fail(command, message);
  return kExitUsage;
}

const std::vector<Layer>& GeoTiffBands() {
  static const std::vector<Layer> bands = {Layer::kElevation,      Layer::kElevationVariance,
                                           Layer::kTraversability, Layer::kTraversabilityVariance,
                                           Layer::kState,          Layer::kDisagreement,
                                           Layer::kBlockReason};
  return bands;
}

}  // namespace bgkmap::cli
