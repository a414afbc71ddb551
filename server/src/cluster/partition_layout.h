// How a cluster cuts the map into partitions: squares of `partition_tiles` x `partition_tiles`
// tiles, each owned by one shard. A shard computes its partitions' cells exactly from the scans
// whose observed cells lie within the halo: the reach of one scan's effect on a cell (kernel
// support twice, robot radius, free-space rays), docs/scale-out.md.
#pragma once

#include <compare>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"

namespace bgkmap::cluster {

struct PartitionKey {
  int x = 0;
  int y = 0;
  friend constexpr auto operator<=>(const PartitionKey&, const PartitionKey&) = default;
};

// "x.y" (e.g. "3.-2"): the partition's name in subjects and KV keys.
std::string PartitionName(PartitionKey p);
std::optional<PartitionKey> ParsePartitionName(std::string_view name);

class PartitionLayout {
 public:
  PartitionLayout(const MapParams& params, int partition_tiles);

  int partition_tiles() const { return partition_tiles_; }
  int halo_cells() const { return halo_cells_; }
  const GridGeometry& geometry() const { return geometry_; }

  PartitionKey PartitionOf(TileKey tile) const;
  PartitionKey PartitionOfCell(CellIndex cell) const { return PartitionOf(geometry_.TileOf(cell)); }
  // The partition's own cells, and those with its halo around them.
  CellBox Cells(PartitionKey p) const;
  CellBox HaloCells(PartitionKey p) const;
  // The first and last tile of the partition.
  TileKey MinTile(PartitionKey p) const;
  TileKey MaxTile(PartitionKey p) const;
  // Partitions with a cell in `box`, sorted.
  std::vector<PartitionKey> Covering(const CellBox& box) const;
  // The cells `scan` can change: its observed cells and its sensor's cell, grown by the halo
  // (empty for a scan with neither).
  CellBox Reach(const PreparedScan& scan) const;
  // Partitions whose cells `scan` can change: those whose halo holds one of its observed cells
  // or its sensor's cell. Sorted.
  std::vector<PartitionKey> Touched(const PreparedScan& scan) const {
    return Covering(Reach(scan));
  }

 private:
  GridGeometry geometry_;
  int partition_tiles_;
  int halo_cells_;
};

}  // namespace bgkmap::cluster
