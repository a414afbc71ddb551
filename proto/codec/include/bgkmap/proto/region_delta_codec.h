// Region deltas <-> bgkmap.v1 messages (docs/server.md, "Region deltas"): a changed tile's part
// of a region raster as a TilePatch, and a patch applied onto a copy of the region.
#pragma once

#include "bgkmap/core/grid.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/v1/query.pb.h"

namespace bgkmap {

// True if every value of every layer of `raster` is, bit for bit, UnknownValue(layer).
bool IsUnknownEverywhere(const Raster& raster);

// The patch of tile `key`: `part`, a raster of TilePatchCells(...) of the region `region`
// (whose raster has the same stride), placed by its rows and columns in the region raster.
// A part unknown everywhere is sent as a tombstone, without values.
void ToProto(TileKey key, const CellBox& region, const Raster& part, v1::TilePatch* out);

// Writes `patch` into `region` (a full answer's raster, or one kept current by deltas): its
// values, or UnknownValue for a tombstone. False, leaving `region` unchanged, if the patch does
// not fit inside it or its layers do not match the raster's (count, order, byte count).
bool ApplyPatch(const v1::TilePatch& patch, Raster* region);

}  // namespace bgkmap
