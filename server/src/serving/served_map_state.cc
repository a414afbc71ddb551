// ServedMap's answer to Info and /metrics: counts, robots, corrections and, on a store, its
// state (MapPort::State).
#include "serving/served_map.h"

namespace bgkmap {
namespace {

StorageState ToStorageState(const StoreStatus& s) {
  StorageState out;
  out.directory = s.directory;
  out.durability = s.durability;
  out.checkpoint_version = s.checkpoint_version;
  out.corrupt_tiles = s.corrupt_tiles;
  out.write_failed = s.write_failed;
  out.writes_paused_for_space = s.writes_paused_for_space;
  out.read_only = s.read_only;
  out.free_bytes = s.free_bytes;
  out.reserve_bytes = s.reserve_bytes;
  out.paused_reason = s.paused_reason;
  const storage::StoreCounters& c = s.counters;
  out.counters = {
      c.tiles_loaded,  c.tiles_written,           c.tiles_deleted,        c.checkpoints,
      c.corrupt_tiles, c.corrupt_log_records,     c.log_records_appended, c.log_bytes_appended,
      c.write_errors,  c.writes_refused_for_space};
  out.usage = {s.usage.tile_bytes,    s.usage.log_bytes, s.usage.sources_bytes,
               s.usage.history_bytes, s.usage.wal_bytes, s.usage.total_bytes};
  return out;
}

}  // namespace

MapState ServedMap::State(bool with_disk_usage) {
  MapState state;
  state.version = applied_version();
  state.scans_applied = scans_applied();
  state.summary = Summary();
  state.robots = Robots();
  state.corrections = corrections();
  state.georeference = durability_.georeference();
  state.tiles = residency_.Stats();
  if (std::optional<StoreStatus> store = durability_.store_status(with_disk_usage)) {
    StorageState& s = state.storage.emplace(ToStorageState(*store));
    s.dirty_tiles = checkpointer_.dirty_tiles();
    s.residency = residency_.Stats();
  }
  return state;
}

}  // namespace bgkmap
