#include "map_store.h"

#include <algorithm>
#include <mutex>

namespace bgkmap {
namespace {

// Cells read per hold of the table lock: small enough that tile creation never waits long.
constexpr int64_t kCellsPerBand = 1 << 18;

}  // namespace

MapStore::MapStore(std::unique_ptr<TerrainMap> map) : map_(std::move(map)) {}

ScanReport MapStore::ApplyScan(const PreparedScan& scan, uint64_t version) {
  std::shared_lock gate(gate_);
  // Read tiles need no lock: the scheduler runs no writer of them now, and readers only read.
  TileLockTable::Guard tiles = tile_locks_.Lock(scan.write_tiles, {});
  TileWindow window;
  {
    std::unique_lock table(table_mu_);
    window = map_->MakeWindow(scan);
  }
  // Integrate() touches only the window's tiles: no table lock, other scans run beside it.
  const uint32_t now = integrations_.fetch_add(1) + 1;
  uint32_t peak = peak_integrations_.load();
  while (now > peak && !peak_integrations_.compare_exchange_weak(peak, now)) {
  }
  ScanReport report = map_->Integrate(scan, window, version);
  integrations_.fetch_sub(1);
  return report;
}

std::vector<TileKey> MapStore::ClearBox(const CellBox& box, uint64_t version) {
  std::unique_lock gate(gate_);  // no scan runs, so no tile appears meanwhile
  const GridGeometry& g = geometry();
  const std::vector<TileKey> existing = ListTiles(g.TileOf(box.min), g.TileOf(box.max));
  TileLockTable::Guard tiles = tile_locks_.Lock(existing, {});
  std::unique_lock table(table_mu_);
  return map_->ClearBox(box, version);
}

void MapStore::SetMapVersion(uint64_t version) {
  std::unique_lock table(table_mu_);
  // Finishing workers report out of order; the map's version only moves forward.
  if (version > map_->version()) map_->set_version(version);
}

void MapStore::AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                        uint64_t version) {
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(keys, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    map_->AddTile(keys[i], *tiles[i]);
    map_->FindMutableTile(keys[i])->set_version(version);
  }
}

void MapStore::ReplaceTiles(std::span<const TileKey> keys,
                            std::span<const std::unique_ptr<Tile>> tiles) {
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(keys, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    if (tiles[i] == nullptr) {
      map_->EraseTile(keys[i]);
    } else {
      map_->SetTile(keys[i], *tiles[i]);
    }
  }
}

Raster MapStore::ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                            int stride) const {
  const GridGeometry& g = geometry();
  TileLockTable::Guard tiles = tile_locks_.LockRange(g.TileOf(box.min), g.TileOf(box.max));

  // Bands of whole stride blocks, north to south, each read under its own table-lock hold.
  const int64_t band_rows = std::max<int64_t>(
      stride, (kCellsPerBand / std::max<int64_t>(box.width(), 1)) / stride * stride);
  Raster out;
  bool first = true;
  for (int64_t top = box.max.y; top >= box.min.y; top -= band_rows) {
    CellBox band = box;
    band.max.y = static_cast<int>(top);
    band.min.y = static_cast<int>(std::max<int64_t>(box.min.y, top - band_rows + 1));
    Raster part;
    {
      std::shared_lock table(table_mu_);
      part = ExtractRaster(*map_, band, layers, stride);
    }
    if (first) {
      out = std::move(part);
      out.box = box;
      first = false;
      continue;
    }
    out.rows += part.rows;
    for (size_t i = 0; i < out.data.size(); ++i) {
      out.data[i].insert(out.data[i].end(), part.data[i].begin(), part.data[i].end());
    }
  }
  return out;
}

std::vector<CellEstimate> MapStore::ReadCells(std::span<const CellIndex> cells) const {
  const GridGeometry& g = geometry();
  std::vector<TileKey> keys;
  keys.reserve(cells.size());
  for (CellIndex c : cells) keys.push_back(g.TileOf(c));
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  TileLockTable::Guard tiles = tile_locks_.Lock({}, keys);
  std::shared_lock table(table_mu_);
  std::vector<CellEstimate> out;
  out.reserve(cells.size());
  for (CellIndex c : cells) out.push_back(map_->Estimate(c));
  return out;
}

TileContent MapStore::ReadTile(TileKey key, const std::vector<Layer>& layers) const {
  const TileKey one[] = {key};
  TileLockTable::Guard tiles = tile_locks_.Lock({}, one);
  std::shared_lock table(table_mu_);
  TileContent out;
  out.raster = ExtractRaster(*map_, geometry().TileBox(key), layers, 1);
  if (const Tile* t = map_->FindTile(key)) out.version = t->version();
  return out;
}

std::vector<TileKey> MapStore::ListTiles(TileKey min, TileKey max) const {
  std::vector<TileKey> keys;
  std::shared_lock table(table_mu_);
  map_->ForEachTile([&](TileKey k, const Tile&) {
    if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) keys.push_back(k);
  });
  std::sort(keys.begin(), keys.end());
  return keys;
}

MapSummary MapStore::Summarize() const {
  std::unique_lock gate(gate_);  // counts of whole scans only
  std::shared_lock table(table_mu_);
  MapSummary s;
  s.tile_count = map_->tile_count();
  s.known_cells = static_cast<uint64_t>(map_->CountKnownCells());
  s.known_bounds = map_->KnownBounds();
  return s;
}

std::vector<std::unique_ptr<Tile>> MapStore::CopyTiles(std::span<const TileKey> keys) const {
  std::shared_lock table(table_mu_);
  std::vector<std::unique_ptr<Tile>> out;
  out.reserve(keys.size());
  for (TileKey k : keys) {
    const Tile* t = map_->FindTile(k);
    out.push_back(t == nullptr ? nullptr : std::make_unique<Tile>(*t));
  }
  return out;
}

std::unique_ptr<TerrainMap> MapStore::Snapshot() const {
  std::unique_lock gate(gate_);
  std::shared_lock table(table_mu_);
  Result<std::unique_ptr<TerrainMap>> copy = TerrainMap::Create(map_->params());
  std::unique_ptr<TerrainMap> out = std::move(copy).value();
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    out->AddTile(k, t);
    out->FindMutableTile(k)->set_version(t.version());
  });
  out->set_version(map_->version());
  return out;
}

}  // namespace bgkmap
