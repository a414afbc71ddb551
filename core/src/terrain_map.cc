#include "bgkmap/core/terrain_map.h"

#include <algorithm>
#include <iterator>

#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

Result<std::unique_ptr<TerrainMap>> TerrainMap::Create(const MapParams& params) {
  if (Status s = params.Validate(); !s.ok()) return s;
  return std::unique_ptr<TerrainMap>(new TerrainMap(params));
}

TerrainMap::TerrainMap(const MapParams& params)
    : params_(params), geometry_(params.resolution, params.tile_size), integrator_(params) {}

Result<ScanReport> TerrainMap::IntegrateScan(std::span<const Point3f> points, const Pose& pose,
                                             bool frame_is_map, int64_t stamp_ns) {
  Result<PreparedScan> scan = PrepareScan(params_, points, pose, frame_is_map);
  if (!scan.ok()) return scan.status();
  scan->stamp_ns = stamp_ns;
  const TileWindow window = MakeWindow(*scan);
  return Integrate(*scan, window, ++version_);
}

TileWindow TerrainMap::MakeWindow(const PreparedScan& scan) {
  const std::vector<TileKey> changeable = scan.ChangeableTiles();
  std::vector<TileKey> keys;
  keys.reserve(changeable.size() + scan.read_tiles.size());
  std::merge(changeable.begin(), changeable.end(), scan.read_tiles.begin(), scan.read_tiles.end(),
             std::back_inserter(keys));
  TileWindow window(keys);
  // The kernels work on dense tiles (a no-op on tiles already dense).
  auto dense = [](Tile* t) {
    if (t != nullptr) t->Unpack();
    return t;
  };
  for (const TileKey& k : scan.write_tiles) window.set(k, dense(&GetOrCreateTile(k)));
  for (const TileKey& k : scan.clear_tiles) window.set(k, dense(FindMutableTile(k)));
  for (const TileKey& k : scan.read_tiles) window.set(k, dense(FindMutableTile(k)));
  return window;
}

ScanReport TerrainMap::Integrate(const PreparedScan& scan, const TileWindow& window,
                                 uint64_t version) const {
  return integrator_.Integrate(scan, window, version);
}

const Tile* TerrainMap::FindTile(TileKey key) const {
  auto it = tiles_.find(key);
  return it == tiles_.end() ? nullptr : it->second.get();
}

Tile* TerrainMap::FindMutableTile(TileKey key) {
  auto it = tiles_.find(key);
  return it == tiles_.end() ? nullptr : it->second.get();
}

Tile& TerrainMap::GetOrCreateTile(TileKey key) {
  std::unique_ptr<Tile>& slot = tiles_[key];
  if (!slot) slot = std::make_unique<Tile>(params_.tile_size, KeepsPlaneMoments(params_.method));
  return *slot;
}

void TerrainMap::EraseTile(TileKey key) { tiles_.erase(key); }

void TerrainMap::ForEachTile(const std::function<void(TileKey, const Tile&)>& fn) const {
  for (const auto& [key, tile] : tiles_) fn(key, *tile);
}

void TerrainMap::AddTile(TileKey key, const Tile& tile) {
  Tile& dst = GetOrCreateTile(key);
  dst.Unpack();
  // Forgetting: both brought to the later stamp, then added (docs/semantics.md "Forgetting").
  if (integrator_.forgetting() && tile.stamp_ns() != dst.stamp_ns()) {
    integrator_.Advance(dst, tile.stamp_ns());
    if (tile.stamp_ns() < dst.stamp_ns()) {
      Tile aged(tile);
      integrator_.Advance(aged, dst.stamp_ns());
      dst.Add(aged);
    } else {
      dst.Add(tile);
    }
  } else {
    dst.Add(tile);
  }
  integrator_.Saturate(dst);
  dst.set_version(std::max(dst.version(), tile.version()));
}

void TerrainMap::SetTile(TileKey key, const Tile& tile) {
  Tile& dst = GetOrCreateTile(key);
  if (tile.has_plane() == dst.has_plane()) {
    dst.Assign(tile);  // in the source's form: a packed tile stays packed
    return;
  }
  if (tile.is_packed()) {
    Tile dense(tile);
    dense.Unpack();
    return SetTile(key, dense);
  }
  dst.Unpack();
  std::copy(tile.w().begin(), tile.w().end(), dst.w().begin());
  std::copy(tile.s().begin(), tile.s().end(), dst.s().begin());
  std::copy(tile.q().begin(), tile.q().end(), dst.q().begin());
  std::copy(tile.a().begin(), tile.a().end(), dst.a().begin());
  std::copy(tile.b().begin(), tile.b().end(), dst.b().begin());
  // A tile without plane moments holds none: the copy's are zero (an empty tile installed in
  // place of a bgk-ll tile must not leave its old moments behind).
  for (int m = 0; dst.has_plane() && m < Tile::kPlaneMoments; ++m) {
    if (tile.has_plane()) {
      std::copy(tile.plane(m).begin(), tile.plane(m).end(), dst.plane(m).begin());
    } else {
      std::fill(dst.plane(m).begin(), dst.plane(m).end(), 0.0);
    }
  }
  dst.set_version(tile.version());
  dst.set_stamp_ns(tile.stamp_ns());
}

CellEstimate TerrainMap::Estimate(CellIndex cell) const {
  const Tile* tile = FindTile(geometry_.TileOf(cell));
  if (tile == nullptr) return EstimateCell(params_, 0.0, 0.0, 0.0, 0.0f, 0.0f);
  const int i = geometry_.LocalIndex(cell);
  double plane[Tile::kPlaneMoments];
  if (tile->has_plane()) tile->PlaneOf(i, plane);
  const Tile::CellStats c = tile->CellAt(i);
  return EstimateCell(params_, c.w, c.s, c.q, c.a, c.b, tile->has_plane() ? plane : nullptr);
}

int64_t TerrainMap::CountKnownCells() const {
  int64_t n = 0;
  for (const auto& entry : tiles_) n += entry.second->CountKnown();
  return n;
}

CellBox TerrainMap::KnownBounds() const {
  CellBox box;
  for (const auto& [key, tile] : tiles_) {
    const TileSummary s = SummarizeTile(geometry_, key, tile.get());
    if (s.known_box.empty()) continue;
    box.Extend(s.known_box.min);
    box.Extend(s.known_box.max);
  }
  return box;
}

std::vector<TileKey> TerrainMap::ClearBox(const CellBox& box, uint64_t version, bool keep_empty) {
  std::vector<TileKey> changed;
  if (box.empty()) return changed;
  const TileKey lo = geometry_.TileOf(box.min), hi = geometry_.TileOf(box.max);
  const int T = params_.tile_size;
  for (auto it = tiles_.begin(); it != tiles_.end();) {
    const TileKey key = it->first;
    if (key.x < lo.x || key.x > hi.x || key.y < lo.y || key.y > hi.y) {
      ++it;
      continue;
    }
    const CellBox part = geometry_.TileBox(key).Intersect(box);
    const CellIndex o = geometry_.TileOrigin(key);
    Tile& tile = *it->second;
    tile.Unpack();
    for (int y = part.min.y; y <= part.max.y; ++y) {
      for (int x = part.min.x; x <= part.max.x; ++x) {
        const int i = (y - o.y) * T + (x - o.x);
        tile.ClearCell(i);
      }
    }
    tile.set_version(version);
    changed.push_back(key);
    it = !keep_empty && tile.Empty() ? tiles_.erase(it) : std::next(it);
  }
  std::sort(changed.begin(), changed.end());
  return changed;
}

size_t TerrainMap::TileMemoryBytes() const {
  size_t bytes = 0;
  for (const auto& entry : tiles_) bytes += entry.second->MemoryBytes();
  return bytes;
}

}  // namespace bgkmap
