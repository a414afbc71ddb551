#include "client_options.h"

#include <cmath>
#include <cstdio>

#include "commands.h"

namespace bgkmap::cli {

void AddServerOption(CLI::App* cmd, std::string& server) {
  server = kDefaultServer;
  cmd->add_option("--server", server, "bgkmapd address host:port")
      ->envname("BGKMAP_SERVER")
      ->capture_default_str();
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
  static const std::vector<Layer> bands = {Layer::kElevation, Layer::kElevationVariance,
                                           Layer::kTraversability, Layer::kTraversabilityVariance,
                                           Layer::kState};
  return bands;
}

}  // namespace bgkmap::cli
