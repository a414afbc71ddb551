// `bgkmap build`: maps a scan sequence or a cloud offline and writes the map as a GeoTIFF.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/octomap_export.h"
#include "bgkmap/io/png_preview.h"
#include "bgkmap/io/progress_bar.h"
#include "commands.h"
#include "scan_source.h"

namespace bgkmap::cli {
namespace {

struct BuildOptions {
  std::string input;
  std::string config;
  std::string out;
  std::string png;
  std::string ot;
  std::string method;
  std::vector<double> bbox;
  std::vector<int> las_classes;
  std::string crs;
  bool cog = false;
};

// The GeoTIFF band contract shared with `bgkmap query`.
const std::vector<Layer> kBands = {Layer::kElevation,      Layer::kElevationVariance,
                                   Layer::kTraversability, Layer::kTraversabilityVariance,
                                   Layer::kState,          Layer::kDisagreement,
                                   Layer::kBlockReason};

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap build: %s\n", msg.c_str());
  return kExitFailure;
}

// A bad command line: the same line, exit code kExitUsage.
int Usage(const std::string& msg) {
  Fail(msg);
  return kExitUsage;
}

int RunBuild(const BuildOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  MapParams params = *loaded;
  if (!o.method.empty()) {
    Result<Method> m = ParseMethod(o.method);
    if (!m.ok()) return Usage(m.status().message());
    params.method = *m;
  }
  if (!o.bbox.empty() &&
      (o.bbox.size() != 4 || !(o.bbox[0] < o.bbox[2]) || !(o.bbox[1] < o.bbox[3]))) {
    return Usage("--bbox: expected xmin,ymin,xmax,ymax with xmin < xmax and ymin < ymax");
  }
  Result<std::unique_ptr<TerrainMap>> created = TerrainMap::Create(params);
  if (!created.ok()) return Fail(created.status().message());
  TerrainMap& map = **created;

  SourceOptions source_options;
  for (int c : o.las_classes) {
    if (c < 0 || c > 255)
      return Usage("--classes: a LAS class is 0..255, got " + std::to_string(c));
    source_options.las_classes.push_back(static_cast<uint8_t>(c));
  }
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.input, source_options);
  if (!source.ok()) return Fail(source.status().message());

  ScanPointCounts total;
  StageTimes times;
  {
    io::ProgressBar progress("mapping", (*source)->size(), "scans");
    double first_time = std::nan("");
    for (size_t k = 0; k < (*source)->size(); ++k) {
      Result<SourceScan> scan = (*source)->Read(k);
      if (!scan.ok()) return Fail(scan.status().message());
      // Map time (forgetting): the sequence's times.txt, its first scan at 1 s (0 would be
      // unstamped); without times, unstamped.
      if (k == 0) first_time = scan->time_s;
      const int64_t stamp = std::isfinite(scan->time_s) && std::isfinite(first_time)
                                ? 1'000'000'000 + std::llround((scan->time_s - first_time) * 1e9)
                                : 0;
      Result<ScanReport> r = map.IntegrateScan(scan->points, scan->pose, scan->frame_is_map, stamp);
      if (!r.ok()) return Fail("scan " + std::to_string(k) + ": " + r.status().message());
      total.input += r->counts.input;
      total.kept += r->counts.kept;
      total.dropped_nonfinite += r->counts.dropped_nonfinite;
      total.dropped_range += r->counts.dropped_range;
      total.dropped_height += r->counts.dropped_height;
      total.dropped_out_of_bounds += r->counts.dropped_out_of_bounds;
      times.elevation += r->times.elevation;
      times.features += r->times.features;
      times.traversability += r->times.traversability;
      progress.Add();
    }
  }

  CellBox box = map.KnownBounds();
  if (!o.bbox.empty()) {
    box = map.geometry().BoxCovering(o.bbox[0], o.bbox[1], o.bbox[2], o.bbox[3]);
    // The far edges are exclusive: a bbox ending on a cell border does not take the next cell.
    const double res = params.resolution;
    if (box.max.x * res >= o.bbox[2] && box.max.x > box.min.x) --box.max.x;
    if (box.max.y * res >= o.bbox[3] && box.max.y > box.min.y) --box.max.y;
  }
  if (box.empty()) return Fail("no cell is known: no scan point survived the filters");
  if (box.cell_count() > 400'000'000) {
    return Fail("output of " + std::to_string(box.width()) + " x " + std::to_string(box.height()) +
                " cells is too large; pass a smaller --bbox");
  }
  const Raster raster = ExtractRaster(map, box, kBands);
  io::GeoTiffOptions tiff;
  tiff.spatial_reference = !o.crs.empty() ? o.crs : (*source)->spatial_reference();
  tiff.cloud_optimized = o.cog;
  if (Status s = io::WriteGeoTiff(raster, o.out, tiff); !s.ok()) return Fail(s.message());
  if (!o.png.empty()) {
    if (Status s = io::WritePreviewPng(raster, o.png); !s.ok()) return Fail(s.message());
  }
  if (!o.ot.empty()) {
    Result<io::OctreeExportResult> ot = io::WriteColorOcTree(raster, o.ot);
    if (!ot.ok()) return Fail(ot.status().message());
    std::printf("bgkmap build: %zu columns -> %s (octree origin %.3f, %.3f in the map frame)\n",
                ot->columns, o.ot.c_str(), ot->origin.x(), ot->origin.y());
  }

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "bgkmap build: %zu scans, %llu points (%llu kept; dropped %llu non-finite, %llu range, "
      "%llu height, %llu out of bounds), %lld known cells, method %s, %.2f s "
      "(elevation %.3f s, features %.3f s, traversability %.3f s) -> %s (%lld x %lld)\n",
      (*source)->size(), static_cast<unsigned long long>(total.input),
      static_cast<unsigned long long>(total.kept),
      static_cast<unsigned long long>(total.dropped_nonfinite),
      static_cast<unsigned long long>(total.dropped_range),
      static_cast<unsigned long long>(total.dropped_height),
      static_cast<unsigned long long>(total.dropped_out_of_bounds),
      static_cast<long long>(map.CountKnownCells()), std::string(MethodName(params.method)).c_str(),
      seconds, times.elevation, times.features, times.traversability, o.out.c_str(),
      static_cast<long long>(raster.cols), static_cast<long long>(raster.rows));
  return 0;
}

}  // namespace

void RegisterBuildCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<BuildOptions>();
  CLI::App* cmd = app.add_subcommand("build",
                                     "Map scans offline (a KITTI-like directory, an OctoMap "
                                     ".graph, or a .las/.pcd cloud) into a GeoTIFF");
  cmd->add_option("input", o->input,
                  "KITTI-like directory (velodyne/*.bin + poses.txt), .graph, .las or .pcd")
      ->required();
  cmd->add_option("--config", o->config, "YAML map parameters (docs/configuration.md)");
  cmd->add_option("--out", o->out, "Output GeoTIFF")->required();
  cmd->add_option("--png", o->png, "Also write a PNG preview (hillshade + traversability)");
  cmd->add_option("--ot", o->ot, "Also write an OctoMap ColorOcTree (.ot) for octovis");
  cmd->add_option(
      "--method", o->method,
      "bgk+ | bgk-trav | baseline | one-step | bgk-obstacle | bgk-ll (overrides config)");
  cmd->add_option("--bbox", o->bbox, "xmin,ymin,xmax,ymax in metres (default: the known cells)")
      ->delimiter(',')
      ->expected(4);
  cmd->add_option("--crs", o->crs,
                  "Coordinate system of the GeoTIFF (EPSG:code, WKT or PROJ); default: the LAS "
                  "file's, else none");
  cmd->add_flag("--cog", o->cog, "Write a Cloud-Optimized GeoTIFF (with overviews)");
  cmd->add_option("--classes", o->las_classes, "LAS: keep only these classes, e.g. 2 for ground")
      ->delimiter(',');
  cmd->callback([o, &exit_code] { exit_code = RunBuild(*o); });
}

}  // namespace bgkmap::cli
