// `bgkmap points`: the chosen layers at a batch of (x, y), as JSON.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "client_options.h"
#include "commands.h"
#include "json_output.h"

namespace bgkmap::cli {
namespace {

struct PointsOptions {
  ServerTarget server;
  std::vector<double> xy;
  std::vector<std::string> layers;
};

int RunPoints(const PointsOptions& o) {
  if (o.xy.empty() || o.xy.size() % 2 != 0) {
    return Usage("points", "expected x,y pairs, e.g. `bgkmap points 1.5,2 -3,4`");
  }
  std::vector<std::array<double, 2>> pts;
  for (size_t i = 0; i < o.xy.size(); i += 2) pts.push_back({o.xy[i], o.xy[i + 1]});
  Result<std::vector<Layer>> layers = ParseLayers(o.layers, GeoTiffBands());
  if (!layers.ok()) return Usage("points", layers.status().message());
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("points", connected.status().message());
  Client& client = **connected;
  RpcResult<PointValues> r = client.QueryPoints(pts, *layers);
  if (!r.ok()) return Fail("points", r.status().ToString());
  nlohmann::json out = {{"map_version", r->map_version}, {"points", nlohmann::json::array()}};
  for (size_t i = 0; i < pts.size(); ++i) {
    nlohmann::json p = {{"x", pts[i][0]}, {"y", pts[i][1]}};
    for (size_t j = 0; j < r->layers.size(); ++j) {
      p[std::string(LayerName(r->layers[j]))] = JsonNumber(r->at(i, j));
    }
    out["points"].push_back(p);
  }
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace

void RegisterPointsCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<PointsOptions>();
  CLI::App* cmd = app.add_subcommand("points", "Layers at map points (JSON; null = unknown)");
  AddServerOption(cmd, o->server);
  cmd->add_option("xy", o->xy, "Points as x,y pairs")->delimiter(',')->required();
  cmd->add_option("--layers", o->layers, "Layers (default: the seven bands)")->delimiter(',');
  cmd->callback([o, &exit_code] { exit_code = RunPoints(*o); });
}

}  // namespace bgkmap::cli
