// `bgkmap build`: maps a scan sequence or a cloud offline and writes the map as a GeoTIFF.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <thread>

#include "bgkmap/config/map_params_yaml.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/crs_check.h"
#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/octomap_export.h"
#include "bgkmap/io/png_preview.h"
#include "bgkmap/io/qgis_style.h"
#include "commands.h"
#include "map_geotiff.h"
#include "map_outputs.h"
#include "output_file.h"
#include "parallel_mapping.h"
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
  SourceOptions source;  // a recording's topic and map frame; LAS classes set below
  bool cog = false;
  std::vector<double> origin;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  double rate_hz = 10.0;  // the scans' spacing in map time without times.txt
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

// The command line's checks that need no input: the parameters, method, bbox, threads, classes
// and the output's kind. On failure the line is printed and the exit code returned.
std::optional<int> CheckCommandLine(const BuildOptions& o, MapParams* params,
                                    SourceOptions* source_options) {
  Result<MapParams> loaded = LoadMapParamsFileOrDefaults(o.config);
  if (!loaded.ok()) return Fail(loaded.status().message());
  *params = *loaded;
  if (!o.method.empty()) {
    Result<Method> m = ParseMethod(o.method);
    if (!m.ok()) return Usage(m.status().message());
    params->method = *m;
  }
  if (!o.bbox.empty() &&
      (o.bbox.size() != 4 || !(o.bbox[0] < o.bbox[2]) || !(o.bbox[1] < o.bbox[3]))) {
    return Usage("--bbox: expected xmin,ymin,xmax,ymax with xmin < xmax and ymin < ymax");
  }
  if (o.threads < 1) return Usage("--threads: expected >= 1, got " + std::to_string(o.threads));
  if (!o.origin.empty() && o.origin.size() != 2 && o.origin.size() != 3) {
    return Usage("--origin: expected E,N or E,N,H");
  }
  if (Result<OutputKind> kind = OutputKindOf(o.out, "--out"); !kind.ok()) {
    return Usage(kind.status().message());
  }
  for (int c : o.las_classes) {
    if (c < 0 || c > 255)
      return Usage("--classes: a LAS class is 0..255, got " + std::to_string(c));
    source_options->las_classes.push_back(static_cast<uint8_t>(c));
  }
  return std::nullopt;
}

// The cells written: the known ones, or --bbox's.
CellBox OutputBox(const BuildOptions& o, const TerrainMap& map) {
  if (o.bbox.empty()) return map.KnownBounds();
  CellBox box = map.geometry().BoxCovering(o.bbox[0], o.bbox[1], o.bbox[2], o.bbox[3]);
  // The far edges are exclusive: a bbox ending on a cell border does not take the next cell.
  const double res = map.params().resolution;
  if (box.max.x * res >= o.bbox[2] && box.max.x > box.min.x) --box.max.x;
  if (box.max.y * res >= o.bbox[3] && box.max.y > box.min.y) --box.max.y;
  return box;
}

// --out (output_file.h: a GeoTIFF, a PNG preview, ROS 2 or Nav2 maps), --png and --ot.
std::optional<int> WriteOutputs(const BuildOptions& o, const Raster& raster,
                                const io::GeoTiffOptions& tiff) {
  if (Status s = WriteMapOutput(raster, o.out, tiff, {}); !s.ok()) return Fail(s.message());
  if (!o.png.empty()) {
    if (Status s = io::WritePreviewPng(raster, o.png); !s.ok()) return Fail(s.message());
  }
  if (!o.ot.empty()) {
    Result<io::OctreeExportResult> ot = io::WriteColorOcTree(raster, o.ot);
    if (!ot.ok()) return Fail(ot.status().message());
    std::printf("bgkmap build: %zu columns -> %s (octree origin %.3f, %.3f in the map frame)\n",
                ot->columns, o.ot.c_str(), ot->origin.x(), ot->origin.y());
  }
  return std::nullopt;
}

void PrintSummary(const BuildOptions& o, size_t scans, const MappingTotals& totals,
                  const TerrainMap& map, const Raster& raster, double seconds) {
  const ScanPointCounts& total = totals.counts;
  const StageTimes& times = totals.times;
  std::printf(
      "bgkmap build: %zu scans, %llu points (%llu kept; dropped %llu non-finite, %llu range, "
      "%llu height, %llu out of bounds), %lld known cells, method %s, %.2f s on %d threads "
      "(CPU: elevation %.3f s, features %.3f s, traversability %.3f s) -> %s (%lld x %lld)\n",
      scans, static_cast<unsigned long long>(total.input),
      static_cast<unsigned long long>(total.kept),
      static_cast<unsigned long long>(total.dropped_nonfinite),
      static_cast<unsigned long long>(total.dropped_range),
      static_cast<unsigned long long>(total.dropped_height),
      static_cast<unsigned long long>(total.dropped_out_of_bounds),
      static_cast<long long>(map.CountKnownCells()),
      std::string(MethodName(map.params().method)).c_str(), seconds, o.threads, times.elevation,
      times.features, times.traversability, o.out.c_str(), static_cast<long long>(raster.cols),
      static_cast<long long>(raster.rows));
}

int RunBuild(const BuildOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  MapParams params;
  SourceOptions source_options = o.source;
  if (std::optional<int> bad = CheckCommandLine(o, &params, &source_options)) return *bad;
  Result<std::unique_ptr<ScanSource>> source = OpenScanSource(o.input, source_options);
  if (!source.ok()) return Fail(source.status().message());
  ReportSkipped("build", **source, source_options);
  io::GeoTiffOptions tiff;
  tiff.spatial_reference = !o.crs.empty() ? o.crs : (*source)->spatial_reference();
  tiff.cloud_optimized = o.cog;
  tiff.threads = o.threads;
  for (size_t i = 0; i < o.origin.size(); ++i) tiff.origin[i] = o.origin[i];
  if (!o.crs.empty()) {  // before any scan is mapped
    const io::CrsUse use{o.crs, "--crs", (*source)->map_frame_is_local(), !o.origin.empty()};
    if (Status s = io::CheckCrsUse(use); !s.ok()) return Usage(s.message());
  } else if (!o.origin.empty()) {
    return Usage("--origin places the map frame in a CRS: pass --crs too");
  }

  MappingTotals totals;
  Result<std::unique_ptr<TerrainMap>> mapped =
      MapScans(params, **source, o.threads, o.rate_hz, &totals);
  if (!mapped.ok()) return Fail(mapped.status().message());
  const TerrainMap& map = **mapped;
  const CellBox box = OutputBox(o, map);
  if (box.empty()) return Fail("no cell is known: no scan point survived the filters");
  if (box.cell_count() > 400'000'000) {
    return Fail("output of " + std::to_string(box.width()) + " x " + std::to_string(box.height()) +
                " cells is too large; pass a smaller --bbox");
  }
  // A GeoTIFF alone is written strip by strip on the threads; the other outputs take the raster.
  const Result<OutputKind> kind = OutputKindOf(o.out, "--out");
  const bool geotiff_only =
      kind.ok() && *kind == OutputKind::kGeoTiff && o.png.empty() && o.ot.empty();
  Raster raster;
  if (geotiff_only) {
    raster = RasterGeometry(map.params().resolution, box, kBands);
    Status written = WriteMapGeoTiff(map, box, kBands, o.out, tiff, o.threads);
    if (written.ok()) written = io::WriteQgisStyle(kBands, o.out);
    if (!written.ok()) return Fail(written.message());
  } else {
    raster = ExtractRaster(map, box, kBands);
    if (std::optional<int> failed = WriteOutputs(o, raster, tiff)) return *failed;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  PrintSummary(o, (*source)->size(), totals, map, raster, seconds);
  return 0;
}

}  // namespace

void RegisterBuildCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<BuildOptions>();
  CLI::App* cmd = app.add_subcommand("build",
                                     "Map scans offline (a KITTI-like directory, a ROS 2 "
                                     "recording, an OctoMap .graph, or a .las/.pcd cloud) into a "
                                     "GeoTIFF");
  cmd->add_option("input", o->input,
                  "KITTI-like directory (velodyne/*.bin + poses.txt), ROS 2 recording (.mcap, "
                  ".db3 or a rosbag2 folder; docs/ros2.md), .graph, .las or .pcd")
      ->required();
  AddRecordingOptions(cmd, o->source);
  cmd->add_option("--config", o->config, "YAML map parameters (docs/configuration.md)");
  cmd->add_option("--out", o->out,
                  "Output GeoTIFF (.tif); X.png: the PNG preview; X.mcap: ROS 2 GridMap, "
                  "OccupancyGrid and Nav2 Costmap; X.yaml: Nav2 map_server YAML + PGM "
                  "(docs/ros2.md)")
      ->required();
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
  cmd->add_option("--threads", o->threads,
                  "Threads for reading, preparing and integrating scans (default: the cores); "
                  "the map is the same bit for bit for any number")
      ->capture_default_str();
  cmd->add_option("--rate", o->rate_hz,
                  "A sequence without times.txt: its scans' rate, Hz, their spacing in map time "
                  "(forgetting, transient objects; default 10)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--origin", o->origin,
                  "E,N[,H]: where the map frame's origin lies in --crs (a scan sequence's frame "
                  "is local: a projected --crs needs it)")
      ->delimiter(',');
  cmd->add_flag("--cog", o->cog, "Write a Cloud-Optimized GeoTIFF (with overviews)");
  cmd->add_option("--classes", o->las_classes, "LAS: keep only these classes, e.g. 2 for ground")
      ->delimiter(',');
  cmd->callback([o, &exit_code] { exit_code = RunBuild(*o); });
}

}  // namespace bgkmap::cli
