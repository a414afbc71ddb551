#include "bgkmap/io/ros_map_messages.h"

#include <fmt/format.h>

#include <cmath>

#include "bgkmap/io/cdr_writer.h"
#include "bgkmap/io/mcap_writer.h"

namespace bgkmap::io {
namespace {

void Header(CdrWriter& w, const RosMapOptions& o) {
  w.I32(static_cast<int32_t>(o.stamp_ns / 1'000'000'000));
  w.U32(static_cast<uint32_t>(o.stamp_ns % 1'000'000'000));
  w.String(o.frame_id);
}

void Time(CdrWriter& w, int64_t ns) {
  w.I32(static_cast<int32_t>(ns / 1'000'000'000));
  w.U32(static_cast<uint32_t>(ns % 1'000'000'000));
}

// geometry_msgs/Pose at (x, y, 0) with no rotation.
void Pose2d(CdrWriter& w, double x, double y) {
  for (double v : {x, y, 0.0, 0.0, 0.0, 0.0, 1.0}) w.F64(v);
}

double SouthEdge(const Raster& r) { return r.y1 - static_cast<double>(r.rows) * r.resolution; }

// The raster's pixel of the cell (col, row-from-south).
size_t Pixel(const Raster& r, int64_t col, int64_t row_from_south) {
  return static_cast<size_t>((r.rows - 1 - row_from_south) * r.cols + col);
}

// Marks the cells within `radius` of a lethal cell as inscribed (253), over a disc stencil.
void Inflate(std::vector<uint8_t>& cost, int64_t cols, int64_t rows, double radius_cells) {
  const int64_t reach = static_cast<int64_t>(std::floor(radius_cells));
  const std::vector<uint8_t> lethal = cost;
  for (int64_t y = 0; y < rows; ++y) {
    for (int64_t x = 0; x < cols; ++x) {
      if (lethal[y * cols + x] != 254) continue;
      for (int64_t dy = -reach; dy <= reach; ++dy) {
        for (int64_t dx = -reach; dx <= reach; ++dx) {
          const int64_t nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= cols || ny >= rows) continue;
          if (double(dx * dx + dy * dy) > radius_cells * radius_cells) continue;
          uint8_t& c = cost[ny * cols + nx];
          if (c < 253) c = 253;
        }
      }
    }
  }
}

// Calls f(index_from_south_west, state, traversability) for every cell.
template <typename F>
Status ForEachCell(const Raster& r, F f) {
  const std::vector<float>* state = r.Find(Layer::kState);
  if (state == nullptr) {
    return Status::InvalidArgument("an occupancy grid or costmap needs the state layer");
  }
  const std::vector<float>* trav = r.Find(Layer::kTraversability);
  for (int64_t y = 0; y < r.rows; ++y) {
    for (int64_t x = 0; x < r.cols; ++x) {
      const size_t p = Pixel(r, x, y);
      f(static_cast<size_t>(y * r.cols + x), static_cast<CellState>((*state)[p]),
        trav ? (*trav)[p] : 0.0f);
    }
  }
  return Status::Ok();
}

}  // namespace

Result<std::vector<int8_t>> OccupancyValues(const Raster& raster) {
  std::vector<int8_t> out(static_cast<size_t>(raster.rows * raster.cols), -1);
  Status s = ForEachCell(raster, [&](size_t i, CellState state, float trav) {
    if (state == CellState::kNonTraversable) {
      out[i] = 100;
    } else if (state == CellState::kTraversable) {
      out[i] = static_cast<int8_t>(
          std::isfinite(trav) ? std::clamp(std::lround(100.0 * trav), 0L, 99L) : 0);
    }
  });
  if (!s.ok()) return s;
  return out;
}

Result<std::vector<uint8_t>> CostmapValues(const Raster& raster, double robot_radius) {
  std::vector<uint8_t> out(static_cast<size_t>(raster.rows * raster.cols), 255);
  Status s = ForEachCell(raster, [&](size_t i, CellState state, float trav) {
    if (state == CellState::kNonTraversable) {
      out[i] = 254;
    } else if (state == CellState::kTraversable) {
      out[i] = static_cast<uint8_t>(
          std::isfinite(trav) ? std::clamp(std::lround(252.0 * trav), 0L, 252L) : 0);
    }
  });
  if (!s.ok()) return s;
  if (robot_radius > 0) Inflate(out, raster.cols, raster.rows, robot_radius / raster.resolution);
  return out;
}

std::string EncodeGridMap(const Raster& r, const RosMapOptions& o) {
  CdrWriter w;
  Header(w, o);
  const double length_x = static_cast<double>(r.cols) * r.resolution;
  const double length_y = static_cast<double>(r.rows) * r.resolution;
  w.F64(r.resolution);
  w.F64(length_x);
  w.F64(length_y);
  Pose2d(w, r.x0 + length_x / 2, r.y1 - length_y / 2);
  w.Length(r.layers.size());
  for (Layer l : r.layers) w.String(LayerName(l));
  const bool has_elevation = r.Find(Layer::kElevation) != nullptr;
  w.Length(has_elevation ? 1 : 0);
  if (has_elevation) w.String(LayerName(Layer::kElevation));
  w.Length(r.layers.size());
  const uint32_t size_x = static_cast<uint32_t>(r.cols), size_y = static_cast<uint32_t>(r.rows);
  std::vector<float> column_major(r.data.empty() ? 0 : r.data[0].size());
  for (const std::vector<float>& layer : r.data) {
    w.Length(2);  // layout.dim: outer (columns = y), inner (rows = x), as grid_map writes it
    w.String("column_index");
    w.U32(size_y);
    w.U32(size_x * size_y);
    w.String("row_index");
    w.U32(size_x);
    w.U32(size_x);
    w.U32(0);  // data_offset
    // grid_map's (i, j): i along -x (raster column cols-1-i), j along -y (raster row j).
    for (uint32_t j = 0; j < size_y; ++j) {
      for (uint32_t i = 0; i < size_x; ++i) {
        column_major[size_t{j} * size_x + i] = layer[size_t{j} * size_x + (size_x - 1 - i)];
      }
    }
    w.Floats(column_major);
  }
  w.U16(0);  // outer_start_index
  w.U16(0);  // inner_start_index
  return w.Take();
}

Result<std::string> EncodeOccupancyGrid(const Raster& r, const RosMapOptions& o) {
  Result<std::vector<int8_t>> values = OccupancyValues(r);
  if (!values.ok()) return values.status();
  CdrWriter w;
  Header(w, o);
  Time(w, o.stamp_ns);  // map_load_time
  w.F32(static_cast<float>(r.resolution));
  w.U32(static_cast<uint32_t>(r.cols));
  w.U32(static_cast<uint32_t>(r.rows));
  Pose2d(w, r.x0, SouthEdge(r));
  w.Bytes({reinterpret_cast<const uint8_t*>(values->data()), values->size()});
  return w.Take();
}

Result<std::string> EncodeCostmap(const Raster& r, const RosMapOptions& o) {
  Result<std::vector<uint8_t>> values = CostmapValues(r, o.robot_radius);
  if (!values.ok()) return values.status();
  CdrWriter w;
  Header(w, o);
  Time(w, o.stamp_ns);  // map_load_time
  Time(w, o.stamp_ns);  // update_time
  w.String("bgkmap");   // layer
  w.F32(static_cast<float>(r.resolution));
  w.U32(static_cast<uint32_t>(r.cols));
  w.U32(static_cast<uint32_t>(r.rows));
  Pose2d(w, r.x0, SouthEdge(r));
  w.Bytes(*values);
  return w.Take();
}

Status WriteRosMapMcap(const Raster& raster, const std::string& path,
                       const RosMapOptions& options) {
  Result<std::string> occupancy = EncodeOccupancyGrid(raster, options);
  if (!occupancy.ok()) return occupancy.status();
  Result<std::string> costmap = EncodeCostmap(raster, options);
  if (!costmap.ok()) return costmap.status();
  McapWriter mcap;
  const auto add = [&](const char* type, const char* topic, std::string data) {
    const uint16_t schema = mcap.AddSchema(type, "ros2msg", RosMapSchemaText(type));
    mcap.AddMessage(mcap.AddChannel(schema, topic), static_cast<uint64_t>(options.stamp_ns),
                    std::move(data));
  };
  add(kGridMapSchema, "/grid_map", EncodeGridMap(raster, options));
  add(kOccupancyGridSchema, "/map", std::move(occupancy).value());
  add(kCostmapSchema, "/costmap", std::move(costmap).value());
  return mcap.WriteFile(path);
}

}  // namespace bgkmap::io
