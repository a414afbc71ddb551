// `bgkmap query`: a region of the served map to a GeoTIFF (the band contract of `bgkmap build`).
#include <cstdio>

#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/octomap_export.h"
#include "bgkmap/io/png_preview.h"
#include "client_options.h"
#include "commands.h"

namespace bgkmap::cli {
namespace {

struct QueryOptions {
  ServerTarget server;
  std::string out, png, ot;
  std::vector<double> bbox;
  std::vector<std::string> layers;
  int stride = 1;
  std::string crs;
  bool cog = false;
};

int RunQuery(const QueryOptions& o) {
  // The command line first: a usage error is one whatever the server says.
  Result<std::vector<Layer>> layers = ParseLayers(o.layers, GeoTiffBands());
  if (!layers.ok()) return Usage("query", layers.status().message());
  if (o.stride < 1) return Usage("query", "--stride must be >= 1");
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("query", connected.status().message());
  Client& client = **connected;
  // Info gives the known bounds and where the map frame sits (server config `georeference`).
  RpcResult<MapInfo> info = client.Info();
  if (!info.ok()) return Fail("query", info.status().ToString());
  MetricBox box;
  if (o.bbox.empty()) {  // default: everything the map knows
    if (info->known_cells == 0) return Fail("query", "the map is empty");
    box = info->known_bounds;
  } else {
    Result<MetricBox> b = ParseBox(o.bbox, "--bbox");
    if (!b.ok()) return Usage("query", b.status().message());
    box = *b;
  }
  uint64_t version = 0;
  RpcResult<Raster> r = client.QueryRegion({box, *layers, o.stride}, &version);
  if (!r.ok()) return Fail("query", r.status().ToString());
  io::GeoTiffOptions tiff;
  tiff.cloud_optimized = o.cog;
  if (!o.crs.empty()) {
    tiff.spatial_reference = o.crs;  // the map frame is in this CRS as it is
  } else if (info->georeference) {
    tiff.spatial_reference = info->georeference->crs;
    tiff.origin = info->georeference->origin;
  }
  if (Status s = io::WriteGeoTiff(*r, o.out, tiff); !s.ok()) return Fail("query", s.message());
  if (!o.png.empty()) {
    if (Status s = io::WritePreviewPng(*r, o.png); !s.ok()) return Fail("query", s.message());
  }
  if (!o.ot.empty()) {
    Result<io::OctreeExportResult> ot = io::WriteColorOcTree(*r, o.ot);
    if (!ot.ok()) return Fail("query", ot.status().message());
    std::printf("bgkmap query: %zu columns -> %s (octree origin %.3f, %.3f in the map frame)\n",
                ot->columns, o.ot.c_str(), ot->origin.x(), ot->origin.y());
  }
  std::printf("bgkmap query: %lld x %lld pixels at %.3f m, map version %llu -> %s\n",
              static_cast<long long>(r->cols), static_cast<long long>(r->rows), r->resolution,
              static_cast<unsigned long long>(version), o.out.c_str());
  return 0;
}

}  // namespace

void RegisterQueryCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<QueryOptions>();
  CLI::App* cmd = app.add_subcommand("query", "Fetch a region of the served map as a GeoTIFF");
  AddServerOption(cmd, o->server);
  cmd->add_option("--bbox", o->bbox, "xmin,ymin,xmax,ymax in metres (default: the known bounds)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--out", o->out, "Output GeoTIFF")->required();
  cmd->add_option("--png", o->png, "Also write a PNG preview");
  cmd->add_option("--ot", o->ot, "Also write an OctoMap ColorOcTree (.ot) for octovis");
  cmd->add_option("--layers", o->layers, "Layers (default: the seven bands of bgkmap build)")
      ->delimiter(',');
  cmd->add_option("--stride", o->stride, "Map cells per output pixel edge")->capture_default_str();
  cmd->add_option("--crs", o->crs,
                  "Coordinate system of the map frame for the GeoTIFF (EPSG:code, WKT or PROJ); "
                  "default: the server's georeference");
  cmd->add_flag("--cog", o->cog, "Write a Cloud-Optimized GeoTIFF (with overviews)");
  cmd->callback([o, &exit_code] { exit_code = RunQuery(*o); });
}

}  // namespace bgkmap::cli
