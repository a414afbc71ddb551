#include "cluster/partition_layout.h"

#include <charconv>

#include "bgkmap/core/scan.h"

namespace bgkmap::cluster {

std::string PartitionName(PartitionKey p) {
  return std::to_string(p.x) + "." + std::to_string(p.y);
}

std::optional<PartitionKey> ParsePartitionName(std::string_view name) {
  const size_t dot = name.find('.');
  if (dot == std::string_view::npos) return std::nullopt;
  PartitionKey p;
  const auto parse = [](std::string_view s, int* out) {
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *out);
    return ec == std::errc() && end == s.data() + s.size() && !s.empty();
  };
  if (!parse(name.substr(0, dot), &p.x) || !parse(name.substr(dot + 1), &p.y)) return std::nullopt;
  return p;
}

PartitionLayout::PartitionLayout(const MapParams& params, int partition_tiles)
    : geometry_(params.resolution, params.tile_size),
      partition_tiles_(partition_tiles),
      halo_cells_(ScanReachCells(params)) {}

PartitionKey PartitionLayout::PartitionOf(TileKey tile) const {
  return {FloorDiv(tile.x, partition_tiles_), FloorDiv(tile.y, partition_tiles_)};
}

TileKey PartitionLayout::MinTile(PartitionKey p) const {
  return {p.x * partition_tiles_, p.y * partition_tiles_};
}

TileKey PartitionLayout::MaxTile(PartitionKey p) const {
  return {p.x * partition_tiles_ + partition_tiles_ - 1,
          p.y * partition_tiles_ + partition_tiles_ - 1};
}

CellBox PartitionLayout::Cells(PartitionKey p) const {
  return {geometry_.TileBox(MinTile(p)).min, geometry_.TileBox(MaxTile(p)).max};
}

CellBox PartitionLayout::HaloCells(PartitionKey p) const {
  CellBox b = Cells(p);
  b.min = {b.min.x - halo_cells_, b.min.y - halo_cells_};
  b.max = {b.max.x + halo_cells_, b.max.y + halo_cells_};
  return b;
}

std::vector<PartitionKey> PartitionLayout::Covering(const CellBox& box) const {
  std::vector<PartitionKey> out;
  if (box.empty()) return out;
  const PartitionKey lo = PartitionOfCell(box.min), hi = PartitionOfCell(box.max);
  for (int x = lo.x; x <= hi.x; ++x) {
    for (int y = lo.y; y <= hi.y; ++y) out.push_back({x, y});
  }
  return out;
}

CellBox PartitionLayout::Reach(const PreparedScan& scan) const {
  CellBox reach;
  for (const ObservedCell& c : scan.cells) reach.Extend(c.cell);
  if (scan.has_sensor) reach.Extend(geometry_.CellAt(scan.sensor_x, scan.sensor_y));
  if (reach.empty()) return reach;
  // A partition's halo holds a cell iff the cell, grown by the halo, meets the partition.
  reach.min = {reach.min.x - halo_cells_, reach.min.y - halo_cells_};
  reach.max = {reach.max.x + halo_cells_, reach.max.y + halo_cells_};
  return reach;
}

}  // namespace bgkmap::cluster
