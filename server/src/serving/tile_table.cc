#include "serving/tile_table.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <sstream>

#include "bgkmap/core/scan_bands.h"

namespace bgkmap {
namespace {

// Cells read per hold of the table lock: small enough that tile creation never waits long.
constexpr int64_t kCellsPerBand = 1 << 18;

// `copy` of each tile at `keys` (null where the map has none).
template <typename Copy>
std::vector<std::unique_ptr<Tile>> CopyEach(const TerrainMap& map, std::span<const TileKey> keys,
                                            Copy copy) {
  std::vector<std::unique_ptr<Tile>> out;
  out.reserve(keys.size());
  for (TileKey k : keys) {
    const Tile* t = map.FindTile(k);
    out.push_back(t == nullptr ? nullptr : copy(*t));
  }
  return out;
}

}  // namespace

TileTable::TileTable(std::unique_ptr<TerrainMap> map, bool keep_cleared, ScanBandOptions bands)
    : map_(std::move(map)), keep_cleared_(keep_cleared), bands_(std::move(bands)) {
  resident_.store(map_->tile_count());
}

uint64_t TileTable::TileBytes() const {
  const uint64_t t = static_cast<uint64_t>(params().tile_size);
  const uint64_t per_cell =
      Tile::kBytesPerCell + (KeepsPlaneMoments(params().method) ? Tile::kPlaneBytesPerCell : 0);
  return sizeof(Tile) + t * t * per_cell;
}

ScanReport TileTable::ApplyScan(const PreparedScan& scan, uint64_t version) {
  std::shared_lock gate(gate_);
  // Read tiles need no lock: the scheduler runs no writer of them now, and readers only read.
  TileLockTable::Guard tiles = tile_locks_.Lock(scan.ChangeableTiles(), {});
  TileWindow window;
  {
    std::unique_lock table(table_mu_);
    // (The scan's pins unpacked these; a tile packed anyway is unpacked here, counted.)
    if (packed_tiles_.load() > 0) {
      for (TileKey k : scan.ChangeableTiles()) UnpackLocked(k);
      for (TileKey k : scan.read_tiles) UnpackLocked(k);
    }
    window = map_->MakeWindow(scan);
    NoteTileCount();
  }
  // Integrate() touches only the window's tiles: no table lock, other scans run beside it.
  const uint32_t now = integrations_.fetch_add(1) + 1;
  uint32_t peak = peak_integrations_.load();
  while (now > peak && !peak_integrations_.compare_exchange_weak(peak, now)) {
  }
  ScanReport report = Integrate(scan, window, version, /*alone=*/now == 1);
  integrations_.fetch_sub(1);
  return report;
}

ScanReport TileTable::Integrate(const PreparedScan& scan, const TileWindow& window,
                                uint64_t version, bool alone) {
  const size_t most =
      alone && bands_.bands > 1 && bands_.offer && bands_.cells_per_band > 0
          ? std::min(static_cast<size_t>(bands_.bands), scan.cells.size() / bands_.cells_per_band)
          : 1;
  const std::vector<TileBand> cut = CutScansIntoBands(params(), {&scan, 1}, static_cast<int>(most));
  if (cut.size() < 2) return map_->Integrate(scan, window, version);
  std::optional<ScanReport> report = IntegrateInBands(
      *map_, scan, window, cut, version, [this](std::span<const std::function<void()>> tasks) {
        RunSharingWithPool(tasks, bands_.offer);
      });
  if (!report) return map_->Integrate(scan, window, version);  // (never for a cut's bands)
  banded_scans_.fetch_add(1);
  return std::move(*report);
}

std::vector<TileKey> TileTable::ClearBox(const CellBox& box, uint64_t version) {
  std::unique_lock gate(gate_);  // no scan runs, so no tile appears meanwhile
  const GridGeometry& g = geometry();
  const std::vector<TileKey> existing = ListTiles(g.TileOf(box.min), g.TileOf(box.max));
  TileLockTable::Guard tiles = tile_locks_.Lock(existing, {});
  std::unique_lock table(table_mu_);
  for (TileKey k : existing) UnpackLocked(k);
  std::vector<TileKey> keys = map_->ClearBox(box, version, keep_cleared_);
  NoteTileCount();
  return keys;
}

Status TileTable::CheckSumsFinite(std::span<const TileKey> keys,
                                  std::span<const Tile* const> tiles) const {
  std::shared_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    const Tile* have = map_->FindTile(keys[i]);
    if (have == nullptr) continue;  // the sum is the (verified, finite) tile itself
    const Tile& add = *tiles[i];
    for (int c = 0; c < add.cell_count(); ++c) {
      const double w = have->w()[c] + add.w()[c], s = have->s()[c] + add.s()[c];
      const double q = have->q()[c] + add.q()[c];
      const float a = have->a()[c] + add.a()[c], b = have->b()[c] + add.b()[c];
      bool plane_finite = true;
      for (int m = 0; add.has_plane() && have->has_plane() && m < Tile::kPlaneMoments; ++m) {
        plane_finite &= std::isfinite(have->plane(m)[c] + add.plane(m)[c]);
      }
      if (std::isfinite(w) && std::isfinite(s) && std::isfinite(q) && std::isfinite(a) &&
          std::isfinite(b) && plane_finite) {
        continue;
      }
      const CellIndex origin = geometry().TileOrigin(keys[i]);
      const int ts = params().tile_size;
      std::ostringstream m;
      m << "tile (" << keys[i].x << ", " << keys[i].y << ") cell (" << origin.x + c % ts << ", "
        << origin.y + c / ts << "): the merged statistics would not be finite (W " << have->w()[c]
        << " + " << add.w()[c] << ", S " << have->s()[c] << " + " << add.s()[c] << ", Q "
        << have->q()[c] << " + " << add.q()[c] << ", A " << have->a()[c] << " + " << add.a()[c]
        << ", B " << have->b()[c] << " + " << add.b()[c]
        << (plane_finite ? ")" : ", or a plane moment)");
      return Status::OutOfRange(m.str());
    }
  }
  return Status::Ok();
}

void TileTable::AddTiles(std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                         uint64_t version) {
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(keys, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    UnpackLocked(keys[i]);
    map_->AddTile(keys[i], *tiles[i]);
    map_->FindMutableTile(keys[i])->set_version(version);
  }
  NoteTileCount();
}

void TileTable::ReplaceTiles(std::span<const TileKey> keys,
                             std::span<const std::unique_ptr<Tile>> tiles) {
  std::unique_lock gate(gate_);
  TileLockTable::Guard locked = tile_locks_.Lock(keys, {});
  std::unique_lock table(table_mu_);
  for (size_t i = 0; i < keys.size(); ++i) {
    ForgetPackedLocked(keys[i]);
    if (tiles[i] == nullptr) {
      map_->EraseTile(keys[i]);
    } else {
      map_->SetTile(keys[i], *tiles[i]);
      CountPackedLocked(keys[i]);
    }
  }
  NoteTileCount();
}

TileLockTable::Guard TileTable::LockShared(std::span<const TileKey> keys) {
  return tile_locks_.Lock({}, keys);
}

TileLockTable::Guard TileTable::LockRangeShared(TileKey min, TileKey max) {
  return tile_locks_.LockRange(min, max);
}

Raster TileTable::ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                             int stride) const {
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

std::vector<CellEstimate> TileTable::ReadCells(std::span<const CellIndex> cells) const {
  std::shared_lock table(table_mu_);
  std::vector<CellEstimate> out;
  out.reserve(cells.size());
  for (CellIndex c : cells) out.push_back(map_->Estimate(c));
  return out;
}

std::pair<Raster, uint64_t> TileTable::ReadTile(TileKey key,
                                                const std::vector<Layer>& layers) const {
  std::shared_lock table(table_mu_);
  const Tile* t = map_->FindTile(key);
  return {ExtractRaster(*map_, geometry().TileBox(key), layers, 1),
          t != nullptr ? t->version() : 0};
}

std::vector<std::unique_ptr<Tile>> TileTable::CopyTiles(std::span<const TileKey> keys) const {
  std::shared_lock table(table_mu_);
  return CopyEach(*map_, keys, [](const Tile& t) { return std::make_unique<Tile>(t); });
}

std::vector<std::unique_ptr<Tile>> TileTable::CopyTilesPacked(std::span<const TileKey> keys) const {
  std::shared_lock table(table_mu_);
  return CopyEach(*map_, keys, &Tile::PackedCopy);
}

std::vector<TileKey> TileTable::ListTiles(TileKey min, TileKey max) const {
  std::vector<TileKey> keys;
  const uint64_t resident = resident_.load();
  const uint64_t w = min.x <= max.x ? uint64_t(int64_t{max.x} - min.x + 1) : 0;
  const uint64_t h = min.y <= max.y ? uint64_t(int64_t{max.y} - min.y + 1) : 0;
  std::shared_lock table(table_mu_);
  // (w, h <= resident first: the whole key space would overflow w * h.)
  if (w > 0 && h > 0 && w <= resident && h <= resident && w * h <= resident) {
    // A small range (a query's): look its keys up rather than walk every tile in memory.
    for (int64_t x = min.x; x <= max.x; ++x) {  // 64-bit: max.x may be INT32_MAX
      for (int64_t y = min.y; y <= max.y; ++y) {
        const TileKey k{static_cast<int>(x), static_cast<int>(y)};
        if (map_->FindTile(k) != nullptr) keys.push_back(k);
      }
    }
    return keys;
  }
  map_->ForEachTile([&](TileKey k, const Tile&) {
    if (k.x >= min.x && k.x <= max.x && k.y >= min.y && k.y <= max.y) keys.push_back(k);
  });
  std::sort(keys.begin(), keys.end());
  return keys;
}

std::vector<TileKey> TileTable::NotResident(std::span<const TileKey> keys) const {
  std::vector<TileKey> out;
  std::shared_lock table(table_mu_);
  for (TileKey k : keys) {
    if (map_->FindTile(k) == nullptr) out.push_back(k);
  }
  return out;
}

std::vector<std::pair<TileKey, TileSummary>> TileTable::SummarizeResident() const {
  std::shared_lock table(table_mu_);
  std::vector<std::pair<TileKey, TileSummary>> out;
  out.reserve(map_->tile_count());
  map_->ForEachTile(
      [&](TileKey k, const Tile& t) { out.emplace_back(k, SummarizeTile(geometry(), k, &t)); });
  return out;
}

std::vector<std::optional<TileSummary>> TileTable::SummarizeIfResident(
    std::span<const TileKey> keys) const {
  std::vector<std::optional<TileSummary>> out;
  out.reserve(keys.size());
  std::shared_lock table(table_mu_);
  for (TileKey k : keys) {
    const Tile* t = map_->FindTile(k);
    out.push_back(t == nullptr ? std::nullopt : std::optional(SummarizeTile(geometry(), k, t)));
  }
  return out;
}

void TileTable::InsertLoaded(std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>& loaded) {
  std::unique_lock table(table_mu_);
  for (auto& [k, tile] : loaded) {
    if (map_->FindTile(k) != nullptr) continue;
    map_->SetTile(k, *tile);
    CountPackedLocked(k);
  }
  NoteTileCount();
}

void TileTable::ForEachResident(const std::function<void(const ResidentTile&)>& fn) const {
  std::shared_lock table(table_mu_);
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    fn({k, t.version(), t.is_packed(), t.is_packed() ? t.MemoryBytes() : TileBytes()});
  });
}

void TileTable::Erase(std::span<const TileKey> keys) {
  std::unique_lock table(table_mu_);
  for (TileKey k : keys) {
    ForgetPackedLocked(k);
    map_->EraseTile(k);
  }
  NoteTileCount();
}

void TileTable::Pack(std::span<const TileKey> keys) {
  std::unique_lock table(table_mu_);
  for (TileKey k : keys) {
    Tile* t = map_->FindMutableTile(k);
    if (t == nullptr || t->is_packed()) continue;
    t->Pack();
    CountPackedLocked(k);
  }
}

void TileTable::Unpack(std::span<const TileKey> keys) {
  if (packed_tiles_.load() == 0) return;
  {
    // Most pins find their tiles dense: look under the shared lock first.
    std::shared_lock table(table_mu_);
    bool any = false;
    for (TileKey k : keys) {
      const Tile* t = map_->FindTile(k);
      if ((any = t != nullptr && t->is_packed())) break;
    }
    if (!any) return;
  }
  std::unique_lock table(table_mu_);
  for (TileKey k : keys) UnpackLocked(k);
}

void TileTable::UnpackLocked(TileKey key) {
  Tile* t = map_->FindMutableTile(key);
  if (t == nullptr || !t->is_packed()) return;
  ForgetPackedLocked(key);
  t->Unpack();
}

void TileTable::ForgetPackedLocked(TileKey key) {
  const Tile* t = map_->FindTile(key);
  if (t == nullptr || !t->is_packed()) return;
  packed_tiles_.fetch_sub(1);
  packed_bytes_.fetch_sub(t->MemoryBytes());
}

void TileTable::CountPackedLocked(TileKey key) {
  const Tile* t = map_->FindTile(key);
  if (t == nullptr || !t->is_packed()) return;
  packed_tiles_.fetch_add(1);
  packed_bytes_.fetch_add(t->MemoryBytes());
}

std::unique_ptr<TerrainMap> TileTable::CopyResident(uint64_t version,
                                                    std::set<TileKey>* resident) const {
  std::unique_lock gate(gate_);
  std::shared_lock table(table_mu_);
  std::unique_ptr<TerrainMap> out = TerrainMap::Create(map_->params()).value();
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    resident->insert(k);
    if (!t.Empty()) out->SetTile(k, t);
  });
  out->set_version(version);
  return out;
}

}  // namespace bgkmap
