// `bgkmap export` and `bgkmap import`: the served map to and from one portable archive file.
#include <cstdio>
#include <optional>

#include "client_options.h"
#include "commands.h"

namespace bgkmap::cli {
namespace {

struct ExportOptions {
  ServerTarget server;
  std::string out;
  std::vector<double> bbox;
};

int RunExport(const ExportOptions& o) {
  std::optional<MetricBox> box;
  if (!o.bbox.empty()) {
    Result<MetricBox> b = ParseBox(o.bbox, "--bbox");
    if (!b.ok()) return Usage("export", b.status().message());
    box = *b;
  }
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("export", connected.status().message());
  Client& client = **connected;
  RpcResult<ExportResult> r = client.ExportMap(box, o.out);
  if (!r.ok()) return Fail("export", r.status().ToString());
  std::printf("bgkmap export: %llu tiles, %llu bytes, map version %llu -> %s\n",
              static_cast<unsigned long long>(r->tiles), static_cast<unsigned long long>(r->bytes),
              static_cast<unsigned long long>(r->map_version), o.out.c_str());
  return 0;
}

struct ImportOptions {
  ServerTarget server;
  std::string in;
};

int RunImport(const ImportOptions& o) {
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("import", connected.status().message());
  Client& client = **connected;
  RpcResult<ImportResult> r = client.ImportMap(o.in);
  if (!r.ok()) return Fail("import", r.status().ToString());
  std::printf(
      "bgkmap import: %llu tiles added from %s (exported at version %llu), map version "
      "%llu, %llu known cells\n",
      static_cast<unsigned long long>(r->tiles_added), o.in.c_str(),
      static_cast<unsigned long long>(r->archive_map_version),
      static_cast<unsigned long long>(r->map_version),
      static_cast<unsigned long long>(r->known_cells));
  return 0;
}

}  // namespace

void RegisterExportCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ExportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "export", "Save the served map (or a region) as one archive file: a consistent snapshot");
  AddServerOption(cmd, o->server);
  cmd->add_option("--bbox,--box", o->bbox, "xmin,ymin,xmax,ymax in metres (default: whole map)")
      ->delimiter(',')
      ->expected(4)
      ->allow_extra_args(false);  // one comma-separated word: OUT may follow
  cmd->add_option("out", o->out, "Archive to write (e.g. map.bgkmap)")->required();
  cmd->callback([o, &exit_code] { exit_code = RunExport(*o); });
}

void RegisterImportCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ImportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "import", "Add an archive into the served map (statistics are summed: a merge)");
  AddServerOption(cmd, o->server);
  cmd->add_option("in", o->in, "Archive written by bgkmap export")->required();
  cmd->callback([o, &exit_code] { exit_code = RunImport(*o); });
}

}  // namespace bgkmap::cli
