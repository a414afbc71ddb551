// `bgkmap query`: a region of the served map to a GeoTIFF (the band contract of `bgkmap build`),
// or with --since, what changed in it after a map version, as JSON (docs/server.md, "Region
// deltas").
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>

#include "bgkmap/client/region_split.h"
#include "bgkmap/io/crs_check.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/geotiff_writer.h"
#include "bgkmap/io/octomap_export.h"
#include "bgkmap/io/png_preview.h"
#include "bgkmap/io/qgis_style.h"
#include "client_options.h"
#include "commands.h"
#include "json_output.h"
#include "map_outputs.h"
#include "output_file.h"

namespace bgkmap::cli {
namespace {

struct QueryOptions {
  ServerTarget server;
  std::string out, png, ot;
  std::vector<double> bbox;
  std::vector<std::string> layers;
  int stride = 1;
  std::string crs;
  std::vector<double> origin;
  std::string frame_id = "map";
  double robot_radius = 0;
  bool cog = false;
  std::optional<uint64_t> since;
  uint64_t history_id = 0;
  bool compress = false;
  uint64_t max_memory_mb = 256;
};

// The answer to --since: which tiles changed (patches and tombstones: a tile's part of the
// region, or at stride 1 rectangles of its changed blocks, so one tile may be listed more than
// once) or why it came back whole.
nlohmann::ordered_json DeltaJson(const RegionDelta& d, uint64_t since) {
  nlohmann::ordered_json j;
  j["answer"] = d.full ? "full_resync" : "delta";
  if (d.full) j["resync_reason"] = d.resync_reason;
  j["since_version"] = since;
  j["map_version"] = d.map_version;
  j["history_id"] = d.history_id;
  j["wire_bytes"] = d.wire_bytes;
  j["cells"] = {d.raster.box.min.x, d.raster.box.min.y, d.raster.box.max.x, d.raster.box.max.y};
  j["stride"] = d.raster.stride;
  j["rows"] = d.raster.rows;
  j["cols"] = d.raster.cols;
  nlohmann::ordered_json tiles = nlohmann::ordered_json::array();
  for (const RegionPatch& p : d.patches) {
    tiles.push_back({{"x", p.key.x},
                     {"y", p.key.y},
                     {"row", p.row_start},
                     {"col", p.col_start},
                     {"rows", p.rows},
                     {"cols", p.cols},
                     {"tombstone", p.tombstone}});
  }
  j["tiles"] = std::move(tiles);
  return j;
}

// --crs (checked already) with --origin, or the server's georeference.
Result<io::GeoTiffOptions> TiffOptions(const QueryOptions& o, const MapInfo& info) {
  io::GeoTiffOptions tiff;
  tiff.cloud_optimized = o.cog;
  if (o.crs.empty()) {
    if (!o.origin.empty()) {
      return Status::InvalidArgument("--origin places the map frame in a CRS: pass --crs too");
    }
    if (info.georeference) {
      tiff.spatial_reference = info.georeference->crs;
      tiff.origin = info.georeference->origin;
    }
    return tiff;
  }
  tiff.spatial_reference = o.crs;
  for (size_t i = 0; i < o.origin.size(); ++i) tiff.origin[i] = o.origin[i];
  return tiff;
}

// The pieces' rasters, stitched; `version` is the newest map version a piece saw (each piece is
// one consistent read, pieces may see different versions).
Result<Raster> ReadPieces(Client& client, const std::vector<MetricBox>& pieces,
                          const RegionQuery& query, uint64_t* version) {
  std::vector<Raster> rasters;
  for (const MetricBox& piece : pieces) {
    uint64_t v = 0;
    RegionQuery q = query;
    q.box = piece;
    RpcResult<Raster> r = client.QueryRegion(q, &v);
    if (!r.ok()) return Status::Unavailable(r.status().ToString());
    *version = std::max(*version, v);
    if (pieces.size() == 1) return std::move(r).value();
    rasters.push_back(std::move(r).value());
  }
  return StitchRasters(rasters);
}

// How a region was read: its geometry, the newest map version, how many queries and windows.
struct RegionRead {
  Raster geometry;  // (no data)
  uint64_t version = 0;
  size_t pieces = 0, windows = 0;
};

// The bytes a raster of the region takes in memory: pixels x layers x 4.
uint64_t RasterBytes(const CellBox& cells, int stride, size_t layers) {
  const Raster g = RasterGeometry(1.0, cells, {}, stride);
  return static_cast<uint64_t>(g.rows) * static_cast<uint64_t>(g.cols) * layers * sizeof(float);
}

// The edge of a GeoTIFF window in pixels: whole blocks, the window's raster within a quarter of
// `max_bytes` (the pieces, the stitched window and GDAL's blocks of it are held at once), at
// least one block.
int64_t WindowPixels(uint64_t max_bytes, size_t layers) {
  const uint64_t pixels = max_bytes / 4 / (layers * sizeof(float));
  const auto edge = static_cast<int64_t>(std::sqrt(static_cast<double>(pixels)));
  return std::max<int64_t>(1, edge / io::kGeoTiffBlockPixels) * io::kGeoTiffBlockPixels;
}

// The region to a GeoTIFF window by window, each window read in pieces within the server's
// limits and written before the next is read, so memory holds one window whatever the size.
Result<RegionRead> StreamGeoTiff(Client& client, const RegionQuery& query, double resolution,
                                 uint64_t budget, int64_t window, const std::string& path,
                                 const io::GeoTiffOptions& tiff) {
  RegionRead read;
  std::unique_ptr<io::GeoTiffWriter> writer;
  const std::vector<MetricBox> windows = RegionWindows(query.box, resolution, query.stride, window);
  for (const MetricBox& w : windows) {
    const std::vector<MetricBox> pieces = SplitRegion(w, resolution, query.stride, budget);
    Result<Raster> r = ReadPieces(client, pieces, query, &read.version);
    if (!r.ok()) return r.status();
    read.pieces += pieces.size();
    if (!writer) {  // the layers and resolution as the server answers them
      read.geometry = RasterGeometry(resolution, RegionCells(query.box, resolution, query.stride),
                                     r->layers, query.stride);
      Result<std::unique_ptr<io::GeoTiffWriter>> created =
          io::GeoTiffWriter::Create(read.geometry, path, tiff);
      if (!created.ok()) return created.status();
      writer = std::move(created).value();
    }
    if (Status s = writer->Write(*r); !s.ok()) return s;
  }
  if (!writer) return Status::InvalidArgument("the region is empty");
  if (Status s = writer->Finish(); !s.ok()) return s;
  if (Status s = io::WriteQgisStyle(read.geometry.layers, path); !s.ok()) return s;
  read.windows = windows.size();
  return read;
}

// The region whole in memory, for the outputs that need it (.png, .mcap, .yaml, --png, --ot).
Result<Raster> ReadWhole(Client& client, const RegionQuery& query, double resolution,
                         uint64_t budget, RegionRead* read) {
  const std::vector<MetricBox> pieces = SplitRegion(query.box, resolution, query.stride, budget);
  Result<Raster> r = ReadPieces(client, pieces, query, &read->version);
  if (!r.ok()) return r.status();
  read->pieces = pieces.size();
  read->windows = 1;
  read->geometry = RasterGeometry(resolution, r->box, r->layers, r->stride);
  return r;
}

// The outputs beside a whole raster: --out of any kind, --png, --ot.
int WriteWholeOutputs(const QueryOptions& o, const Raster& r, const io::GeoTiffOptions& tiff) {
  io::RosMapOptions ros;
  ros.frame_id = o.frame_id;
  ros.robot_radius = o.robot_radius;
  ros.stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::system_clock::now().time_since_epoch())
                     .count();
  if (Status s = WriteMapOutput(r, o.out, tiff, ros); !s.ok()) return Fail("query", s.message());
  if (!o.png.empty()) {
    if (Status s = io::WritePreviewPng(r, o.png); !s.ok()) return Fail("query", s.message());
  }
  if (!o.ot.empty()) {
    Result<io::OctreeExportResult> ot = io::WriteColorOcTree(r, o.ot);
    if (!ot.ok()) return Fail("query", ot.status().message());
    std::printf("bgkmap query: %zu columns -> %s (octree origin %.3f, %.3f in the map frame)\n",
                ot->columns, o.ot.c_str(), ot->origin.x(), ot->origin.y());
  }
  return 0;
}

int RunQuery(const QueryOptions& o) {
  // The command line first: a usage error is one whatever the server says.
  Result<std::vector<Layer>> layers = ParseLayers(o.layers, GeoTiffBands());
  if (!layers.ok()) return Usage("query", layers.status().message());
  if (o.stride < 1) return Usage("query", "--stride must be >= 1");
  if (!(o.robot_radius >= 0) || !std::isfinite(o.robot_radius)) {
    return Usage("query", "--robot-radius must be a finite number >= 0");
  }
  if (!o.origin.empty() && o.origin.size() != 2 && o.origin.size() != 3) {
    return Usage("query", "--origin: expected E,N or E,N,H");
  }
  if (o.since && (!o.out.empty() || !o.png.empty() || !o.ot.empty())) {
    return Usage("query",
                 "--since prints the changed tiles as JSON; --out, --png and --ot need the whole "
                 "region (the Python MapMirror and the C++ client's ApplyDelta keep a copy)");
  }
  if (!o.since && o.out.empty()) return Usage("query", "--out is required");
  if (!o.since) {
    Result<OutputKind> kind = OutputKindOf(o.out, "--out");
    if (!kind.ok()) return Usage("query", kind.status().message());
  }
  if (!o.crs.empty()) {
    // The map frame is local unless told where it lies: the server's georeference places it in
    // its own CRS, not in --crs.
    const io::CrsUse use{o.crs, "--crs", true, !o.origin.empty()};
    if (Status s = io::CheckCrsUse(use); !s.ok()) return Usage("query", s.message());
  }
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("query", connected.status().message());
  Client& client = **connected;
  // Info gives the known bounds and where the map frame sits (server config `georeference`).
  RpcResult<MapInfo> info = client.Info();
  if (!info.ok()) return Fail("query", info.status().ToString());
  Result<io::GeoTiffOptions> tiff = TiffOptions(o, *info);
  if (!tiff.ok()) return Usage("query", tiff.status().message());
  MetricBox box;
  if (o.bbox.empty()) {  // default: everything the map knows
    if (info->known_cells == 0) return Fail("query", "the map is empty");
    box = info->known_bounds;
  } else {
    Result<MetricBox> b = ParseBox(o.bbox, "--bbox");
    if (!b.ok()) return Usage("query", b.status().message());
    box = *b;
  }
  if (o.since) {
    RpcResult<RegionDelta> d =
        client.QueryRegionSince({box, *layers, o.stride, o.compress}, *o.since, o.history_id);
    if (!d.ok()) return Fail("query", d.status().ToString());
    std::fputs(JsonText(DeltaJson(*d, *o.since)).c_str(), stdout);
    return 0;
  }
  // A region over the server's per-query limits is read in pieces (region_split.h). A GeoTIFF
  // alone is streamed window by window with bounded memory; the other outputs need the whole
  // raster, within --max-memory-mb.
  const double res = info->params.resolution;
  const uint64_t budget = RegionCellBudget(info->limits, o.stride);
  const uint64_t max_bytes = o.max_memory_mb << 20;
  const RegionQuery query{box, *layers, o.stride, o.compress};
  const bool streamed =
      *OutputKindOf(o.out, "--out") == OutputKind::kGeoTiff && o.png.empty() && o.ot.empty();
  RegionRead read;
  if (streamed) {
    tiff->cog_cache_bytes = max_bytes / 4;  // the COG driver's copy: GDAL's cache, a window's worth
    Result<RegionRead> r = StreamGeoTiff(client, query, res, budget,
                                         WindowPixels(max_bytes, layers->size()), o.out, *tiff);
    if (!r.ok()) return Fail("query", r.status().message());
    read = std::move(r).value();
  } else {
    const uint64_t bytes = RasterBytes(RegionCells(box, res, o.stride), o.stride, layers->size());
    if (bytes > max_bytes) {
      return Usage("query", "the region is " + std::to_string((bytes + (1 << 20) - 1) >> 20) +
                                " MB in memory at --stride " + std::to_string(o.stride) +
                                ", over --max-memory-mb " + std::to_string(o.max_memory_mb) +
                                ": a .png, .mcap or .yaml output, --png and --ot need the whole "
                                "raster; a GeoTIFF alone (.tif) is written in windows of any "
                                "size, or use a coarser --stride or a larger --max-memory-mb");
    }
    Result<Raster> r = ReadWhole(client, query, res, budget, &read);
    if (!r.ok()) return Fail("query", r.status().message());
    if (int code = WriteWholeOutputs(o, *r, *tiff); code != 0) return code;
  }
  std::string parts;
  if (read.pieces > 1) parts = " (" + std::to_string(read.pieces) + " pieces";
  if (read.windows > 1) parts += " in " + std::to_string(read.windows) + " windows";
  if (!parts.empty()) parts += ")";
  std::printf("bgkmap query: %lld x %lld pixels at %.3f m, map version %llu%s -> %s\n",
              static_cast<long long>(read.geometry.cols),
              static_cast<long long>(read.geometry.rows), read.geometry.resolution,
              static_cast<unsigned long long>(read.version), parts.c_str(), o.out.c_str());
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
  cmd->add_option("--out", o->out,
                  "Output GeoTIFF (.tif); X.png: the PNG preview; X.mcap: ROS 2 GridMap, "
                  "OccupancyGrid and Nav2 Costmap; X.yaml: Nav2 map_server YAML + PGM "
                  "(docs/ros2.md); required unless --since");
  cmd->add_option("--frame-id", o->frame_id, ".mcap: the messages' frame_id")
      ->capture_default_str();
  cmd->add_option("--robot-radius", o->robot_radius,
                  ".mcap: the costmap's cells within this many metres of a lethal cell are "
                  "inscribed (253); 0: no inflation")
      ->capture_default_str();
  cmd->add_option("--png", o->png, "Also write a PNG preview");
  cmd->add_option("--ot", o->ot, "Also write an OctoMap ColorOcTree (.ot) for octovis");
  cmd->add_option("--layers", o->layers, "Layers (default: the seven bands of bgkmap build)")
      ->delimiter(',');
  cmd->add_option("--stride", o->stride, "Map cells per output pixel edge")->capture_default_str();
  cmd->add_option("--crs", o->crs,
                  "Coordinate system of the map frame for the GeoTIFF (EPSG:code, WKT or PROJ); "
                  "default: the server's georeference");
  cmd->add_option("--origin", o->origin,
                  "E,N[,H]: where the map frame's origin lies in --crs (a projected --crs needs "
                  "it)")
      ->delimiter(',');
  cmd->add_flag("--cog", o->cog, "Write a Cloud-Optimized GeoTIFF (with overviews)");
  cmd->add_option("--since", o->since,
                  "Print as JSON which tiles of the region changed after this map version "
                  "(patches and tombstones: a tile's part, or rectangles of its changed blocks), "
                  "or why the server answers the whole region");
  cmd->add_flag("--compress", o->compress,
                "Have the server gzip the answer on the wire (RegionRequest.compress)");
  cmd->add_option("--max-memory-mb", o->max_memory_mb,
                  "Bound on the rasters held in memory: a GeoTIFF is written in windows of "
                  "whole 256-pixel blocks within a quarter of it (at least one block), any "
                  "region size; .png, .mcap, .yaml, --png and --ot need the whole raster within "
                  "it")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t{1}, uint64_t{1} << 30));
  cmd->add_option("--history-id", o->history_id,
                  "With --since: the history_id the version came from (0: not checked)");
  cmd->callback([o, &exit_code] { exit_code = RunQuery(*o); });
}

}  // namespace bgkmap::cli
