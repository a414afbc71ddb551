// `bgkmap clear`: forget every cell of a region (admin).
#include <cstdio>

#include "client_options.h"
#include "commands.h"

namespace bgkmap::cli {
namespace {

struct ClearOptions {
  ServerTarget server;
  std::vector<double> bbox;
  bool yes = false;
};

int RunClear(const ClearOptions& o) {
  Result<MetricBox> box = ParseBox(o.bbox, "--bbox");
  if (!box.ok()) return Usage("clear", box.status().message());
  if (!o.yes) return Usage("clear", "this erases map data; pass --yes to confirm");
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("clear", connected.status().message());
  Client& client = **connected;
  RpcResult<ClearResult> r = client.ClearRegion(*box);
  if (!r.ok()) return Fail("clear", r.status().ToString());
  std::printf("bgkmap clear: %zu tiles changed, map version %llu\n", r->changed_tiles.size(),
              static_cast<unsigned long long>(r->map_version));
  return 0;
}

}  // namespace

void RegisterClearCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ClearOptions>();
  CLI::App* cmd = app.add_subcommand("clear", "Erase a region of the served map (admin)");
  AddServerOption(cmd, o->server);
  cmd->add_option("--bbox", o->bbox, "xmin,ymin,xmax,ymax in metres")
      ->delimiter(',')
      ->expected(4)
      ->required();
  cmd->add_flag("--yes", o->yes, "Confirm");
  cmd->callback([o, &exit_code] { exit_code = RunClear(*o); });
}

}  // namespace bgkmap::cli
