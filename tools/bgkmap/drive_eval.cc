#include "drive_eval.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/terrain_features.h"
#include "bgkmap/io/geotiff.h"
#include "drive_figure.h"

namespace bgkmap::cli {
namespace {

namespace fs = std::filesystem;

// One line per driven cell on the map after scan k: its statistics, state and reasons, whether
// scan k has a return in it and, where it has, the features v was computed from (up to the
// footprint evidence the traversability step adds after them).
void WriteTrace(std::ostream& out, size_t k, const TerrainMap& map,
                const std::vector<eval::DrivenCell>& driven, const SourceScan& scan) {
  Result<PreparedScan> prepared = PrepareScan(map.params(), scan.points, scan.pose);
  std::vector<CellIndex> observed;
  if (prepared.ok()) {
    for (const ObservedCell& c : prepared->cells) observed.push_back(c.cell);
  }
  for (const eval::DrivenCell& d : driven) {
    const Tile* t = map.FindTile(map.geometry().TileOf(d.cell));
    const int i = map.geometry().LocalIndex(d.cell);
    const double w = t ? t->w()[i] : 0.0, s = t ? t->s()[i] : 0.0, q = t ? t->q()[i] : 0.0;
    const CellEstimate e = map.Estimate(d.cell);
    const bool seen = std::binary_search(observed.begin(), observed.end(), d.cell);
    out << k << ',' << d.cell.x << ',' << d.cell.y << ',' << seen << ',' << w << ',' << e.elevation
        << ',' << Disagreement(w, s, q) << ',' << (t ? t->a()[i] : 0.0f) << ','
        << (t ? t->b()[i] : 0.0f) << ',' << static_cast<int>(e.state) << ','
        << static_cast<int>(eval::BlockReasonsAt(map, d.cell));
    TerrainFeatures f;
    if (seen && eval::SurfaceFeatures(map, d.cell, &f)) {
      out << ',' << f.step << ',' << f.slope_deg << ',' << f.roughness << ','
          << TraversabilityValue(f, map.params()) << '\n';
    } else {
      out << ",,,,\n";
    }
  }
}

}  // namespace

Status LoadTraffic(const std::string& path, const MapParams& params, DriveInputs* in) {
  std::ifstream f(path);
  if (!f) return Status::IoError(path + ": cannot read");
  try {
    const nlohmann::json j = nlohmann::json::parse(f);
    const double res = j.at("resolution").get<double>();
    const double radius = j.at("robot_radius").get<double>();
    if (std::abs(res - params.resolution) > 1e-9 || std::abs(radius - params.robot_radius) > 1e-9)
      return Status::InvalidArgument(path +
                                     ": made with another resolution or robot_radius "
                                     "than the map's (pass the simulation's --config)");
    for (const auto& v : j.at("vehicles")) {
      eval::VehicleTrack t;
      t.name = v.value("name", "");
      t.first_scan = v.at("first_scan").get<int>();
      for (const auto& b : v.at("boxes")) t.boxes.push_back(b.get<std::array<double, 4>>());
      in->vehicles.push_back(std::move(t));
    }
  } catch (const nlohmann::json::exception& e) {
    return Status::InvalidArgument(path + ": " + e.what());
  }
  const std::string truth_path =
      (fs::path(path).parent_path() / "ground_truth_static.tif").string();
  Result<Raster> truth = io::ReadGeoTiff(truth_path);
  if (!truth.ok()) return truth.status();
  if (truth->Find(Layer::kState) == nullptr || truth->stride != 1)
    return Status::InvalidArgument(truth_path + ": needs a state band at the map's resolution");
  in->static_truth = std::move(truth).value();
  return Status::Ok();
}

DriveObserver::DriveObserver(const MapParams& params, const std::string& method,
                             const DriveInputs& in, const std::vector<SourceScan>& scans,
                             const DriveOutputs& out)
    : method_(method), in_(in), scans_(scans), out_(out) {
  if (in.static_truth) {
    traffic_.emplace(params, in.vehicles, static_cast<int>(scans.size()), *in.static_truth,
                     in.observed, out.trail_scans, out.new_scans);
  }
  if (!in.footprint) return;
  std::function<bool(int, CellIndex)> near_vehicle;
  if (traffic_) near_vehicle = [this](int k, CellIndex c) { return traffic_->Near(k, c); };
  causes_.emplace(in.driven, near_vehicle);
  if (!out.trace.empty()) {
    const fs::path path = fs::path(out.dir) / (method + "_" + out.trace);
    trace_.open(path);
    if (!trace_) error_ = Status::IoError(path.string() + ": cannot write");
    trace_ << "scan,ix,iy,observed,w,elevation,disagreement,a,b,state,reasons,step,slope,"
              "roughness,v\n";
  }
}

void DriveObserver::AfterScan(size_t k, const TerrainMap& map) {
  if (traffic_) traffic_->Score(static_cast<int>(k), map);
  if (!in_.footprint) return;
  if (trace_.is_open()) WriteTrace(trace_, k, map, in_.driven, scans_[k]);
  causes_->AfterScan(static_cast<int>(k), in_.path[k], map);
  // The ground the next scan arrives at, on the map before it.
  if (k + 1 < in_.arrivals.size()) on_arrival_ += eval::ScoreDrive(map, in_.arrivals[k + 1]);
  if (std::count(out_.figure_scans.begin(), out_.figure_scans.end(), static_cast<int>(k)) > 0) {
    const std::string png =
        (fs::path(out_.dir) / ("drive_" + method_ + "_scan" + std::to_string(k) + ".png")).string();
    // A square of 30 m around the sensor of scan k.
    const Eigen::Vector3d& t = in_.path[k].translation;
    const CellBox around =
        map.geometry().BoxCovering(t.x() - 15.0, t.y() - 15.0, t.x() + 15.0, t.y() + 15.0);
    if (Status s = WriteDriveFigure(map, in_.driven, png, around); !s.ok() && error_.ok())
      error_ = s;
  }
}

Status DriveObserver::Finish(const TerrainMap& map, MethodResult* m) {
  if (!error_.ok()) return error_;
  if (trace_.is_open() && !trace_.flush())
    return Status::IoError(out_.dir + ": cannot write the trace");
  if (traffic_) m->traffic = traffic_->counts();
  if (!in_.footprint) return Status::Ok();
  m->drive = eval::ScoreDrive(map, in_.driven);
  m->drive_on_arrival = on_arrival_;
  causes_->Finish(map);
  m->causes_final = causes_->final();
  m->causes_on_arrival = causes_->on_arrival();
  if (!out_.figures) return Status::Ok();
  return WriteDriveFigure(map, in_.driven,
                          (fs::path(out_.dir) / ("drive_" + method_ + ".png")).string());
}

}  // namespace bgkmap::cli
