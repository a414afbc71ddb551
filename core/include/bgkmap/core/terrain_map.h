// The tiled terrain map: tiles of sufficient statistics in a hash table keyed by tile
// coordinates (unbounded extent over the int32 cell range), plus the integrator.
//
// Thread-compatibility: const methods may run concurrently with each other. Mutating methods
// need exclusive access, except Integrate(), which touches only the tiles of the window it is
// given: integrations of scans with disjoint tile sets may run concurrently once MakeWindow()
// (which may create tiles and so needs exclusive access) has resolved their windows.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <unordered_map>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/tile.h"

namespace bgkmap {

class TerrainMap {
 public:
  // Fails if the parameters do not validate.
  static Result<std::unique_ptr<TerrainMap>> Create(const MapParams& params);

  const MapParams& params() const { return params_; }
  const GridGeometry& geometry() const { return geometry_; }
  const ScanIntegrator& integrator() const { return integrator_; }

  // Prepares and integrates one scan taken at map time `stamp_ns` (forgetting's clock; 0:
  // unstamped); on error the map is unchanged. Increments version().
  Result<ScanReport> IntegrateScan(std::span<const Point3f> points, const Pose& T_map_sensor,
                                   bool frame_is_map = false, int64_t stamp_ns = 0);

  // The two halves of IntegrateScan for callers that schedule scans themselves.
  TileWindow MakeWindow(const PreparedScan& scan);  // creates scan.write_tiles (not clear_tiles)
  ScanReport Integrate(const PreparedScan& scan, const TileWindow& window, uint64_t version) const;

  // Map version: number of scans and edits applied (stamped on changed tiles).
  uint64_t version() const { return version_; }
  void set_version(uint64_t v) { version_ = v; }

  // Tiles.
  const Tile* FindTile(TileKey key) const;
  Tile* FindMutableTile(TileKey key);
  Tile& GetOrCreateTile(TileKey key);
  void EraseTile(TileKey key);
  size_t tile_count() const { return tiles_.size(); }
  void ForEachTile(const std::function<void(TileKey, const Tile&)>& fn) const;
  // Adds `tile`'s statistics into the tile at `key` (creating it): the merge of two maps. With
  // forgetting, both are first brought to the later of their stamps.
  void AddTile(TileKey key, const Tile& tile);
  // Makes the tile at `key` a bitwise copy of `tile`, version and stamp included (AddTile onto an
  // empty tile would not be: 0 + -0 is +0), in `tile`'s form (packed or dense).
  void SetTile(TileKey key, const Tile& tile);

  // Cells.
  CellEstimate Estimate(CellIndex cell) const;
  CellEstimate EstimateAt(double x, double y) const { return Estimate(geometry_.CellAt(x, y)); }
  int64_t CountKnownCells() const;
  CellBox KnownBounds() const;  // empty if no cell is known
  // Zeroes the statistics of every cell inside `box`, stamps the changed tiles with `version`
  // (like Integrate) and drops tiles left empty unless `keep_empty` (a caller whose tiles are
  // also stored elsewhere needs the emptied tile as a record of the clear); returns the tiles
  // that changed.
  std::vector<TileKey> ClearBox(const CellBox& box, uint64_t version, bool keep_empty = false);
  // The same as the next change of this map: ClearBox(box, version() + 1), version() advanced.
  std::vector<TileKey> ClearBox(const CellBox& box) { return ClearBox(box, ++version_); }

  // Bytes held by tile storage, each tile in its form (what "bytes per known cell" divides).
  size_t TileMemoryBytes() const;

 private:
  explicit TerrainMap(const MapParams& params);

  MapParams params_;
  GridGeometry geometry_;
  ScanIntegrator integrator_;
  uint64_t version_ = 0;
  std::unordered_map<TileKey, std::unique_ptr<Tile>, TileKeyHash> tiles_;
};

}  // namespace bgkmap
