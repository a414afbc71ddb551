"""What the client's calls return: scans going in, acks, rasters, path checks, tile updates."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, Iterator, Optional

import grpc
import numpy as np


@dataclasses.dataclass
class Scan:
    """One lidar scan for `Client.insert_stream`.

    points: Nx3 or Nx4 array (x, y, z[, intensity]) in the sensor frame; sent as float32 x, y, z.
    pose: the sensor pose T_map_sensor as a 4x4 (or 3x4) matrix.
    robot, seq: robot id and its increasing sequence number (a repeated number is a duplicate).
    stamp: seconds since the Unix epoch (float) or a datetime; None: the time it is sent."""

    points: Any
    pose: Any
    robot: str
    seq: int
    stamp: Any = None


@dataclasses.dataclass
class ScanAck:
    """The server's answer to one scan.

    status: "applied", "duplicate" (this or a higher sequence number was already admitted; not
    applied again) or "rejected" (see code and message; the map is unchanged by this scan)."""

    robot_id: str
    sequence: int
    status: str
    code: grpc.StatusCode
    message: str
    changed_tiles: list  # [(x, y), ...] tile keys the scan changed, sorted
    map_version: int
    counts: dict  # input, kept, dropped_nonfinite, dropped_range, dropped_height, dropped_out_of_bounds

    @property
    def ok(self) -> bool:
        return self.status != "rejected"


class Region(Mapping):
    """Layers over a region: a mapping from layer name to a float32 array of shape (rows, cols).

    Rows run north to south (row 0 holds the largest y), columns west to east, like the C++
    client's Raster and the GeoTIFF; NaN is unknown (the state layer uses 0). With stride s > 1 a
    pixel aggregates s x s map cells (elevation from their summed statistics, the worst
    traversability and its variance)."""

    def __init__(self, layers: dict, *, x0: float, y1: float, resolution: float, stride: int,
                 cells: tuple, map_version: int, history_id: int = 0, wire_bytes: int = 0):
        self.layers = layers
        self.x0 = x0                  # west edge, metres
        self.y1 = y1                  # north edge, metres
        self.resolution = resolution  # pixel edge, metres (map resolution x stride)
        self.stride = stride
        self.cells = cells            # covered map cells (min_x, min_y, max_x, max_y), inclusive
        self.map_version = map_version
        self.history_id = history_id  # the server's; with map_version, what a delta asks from
        self.wire_bytes = wire_bytes  # serialized size of the answer's messages
        first = next(iter(layers.values()), None)
        self.rows, self.cols = (0, 0) if first is None else first.shape

    def __getitem__(self, name: str) -> np.ndarray:
        return self.layers[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.layers)

    def __len__(self) -> int:
        return len(self.layers)

    def __repr__(self) -> str:
        return (f"Region({list(self.layers)}, {self.rows}x{self.cols}, x0={self.x0}, y1={self.y1},"
                f" resolution={self.resolution}, map_version={self.map_version})")

    @property
    def geotransform(self) -> tuple:
        """GDAL's affine geotransform (x0, dx, 0, y1, 0, -dy): pixel (col, row) has its north-west
        corner at (x0 + col * dx, y1 - row * dy)."""
        return (self.x0, self.resolution, 0.0, self.y1, 0.0, -self.resolution)

    @property
    def bounds(self) -> tuple:
        """(xmin, ymin, xmax, ymax) of the raster, metres."""
        return (self.x0, self.y1 - self.rows * self.resolution,
                self.x0 + self.cols * self.resolution, self.y1)

    def xy(self, row, col):
        """Map coordinates of pixel centres (scalars or arrays)."""
        row = np.asarray(row)
        col = np.asarray(col)
        return (self.x0 + (col + 0.5) * self.resolution, self.y1 - (row + 0.5) * self.resolution)

    def index(self, x, y):
        """(row, col) of the pixels holding map points (may lie outside the raster). A point on a
        cell edge belongs to the cell above it, as in the server (cell i covers
        [i * res, (i + 1) * res)), so region[layer][index(x, y)] is what points() answers."""
        cell = self.resolution / self.stride  # the map's resolution
        cx = np.floor(np.asarray(x, dtype=np.float64) / cell).astype(np.int64)
        cy = np.floor(np.asarray(y, dtype=np.float64) / cell).astype(np.int64)
        return (self.cells[3] - cy) // self.stride, (cx - self.cells[0]) // self.stride

    def to_xarray(self):
        """The region as an xarray.Dataset with x and y coordinates of pixel centres (needs Debian's
        python3-xarray, an optional extra)."""
        try:
            import xarray
        except ImportError as e:  # an optional extra: say how to get it
            raise ImportError("Region.to_xarray needs xarray (apt-get install python3-xarray)") from e
        rows = np.arange(self.rows)
        cols = np.arange(self.cols)
        x, _ = self.xy(0, cols)
        _, y = self.xy(rows, 0)
        return xarray.Dataset(
            {name: (("y", "x"), values) for name, values in self.layers.items()},
            coords={"x": x, "y": y},
            attrs={"geotransform": self.geotransform, "map_version": self.map_version,
                   "stride": self.stride})


@dataclasses.dataclass
class PathCheck:
    """Footprint safety along a path: at its poses and along the straight segments between them
    (placements at most a cell apart, docs/semantics.md "Path checks").

    safe: every pose and every placement between consecutive poses is safe.
    poses: a structured array, one record per pose: x, y, yaw, worst_traversability (NaN if no
    cell is known), worst_traversability_variance, unknown_fraction, cell_count, safe.
    segments: a structured array, one record per segment (len(poses) - 1; segment i joins poses
    i and i + 1): safe, placement_count (placements strictly between the two poses).
    first_unsafe_point: None when safe, else a dict of the first unsafe placement in path order:
    x, y, yaw, segment, t (0 at poses[segment] itself, 0 < t < 1 between it and the next pose)
    and its footprint's verdict (the pose fields above).
    first_unsafe_index: None when safe, else first_unsafe_point["segment"]: the pose where the
    unsafe stretch begins (that pose may itself be safe when the trouble lies after it)."""

    safe: bool
    first_unsafe_index: Optional[int]
    poses: np.ndarray
    map_version: int
    segments: np.ndarray = None
    first_unsafe_point: Optional[dict] = None

    def __bool__(self) -> bool:
        return self.safe


@dataclasses.dataclass
class TileUpdate:
    """The current content of one changed tile (Client.watch).

    layers: layer name -> float32 array (tile_size, tile_size), rows north to south."""

    key: tuple  # (x, y)
    tile_version: int
    map_version: int
    cells: tuple  # (min_x, min_y, max_x, max_y), inclusive
    resolution: float
    layers: dict

    @property
    def geotransform(self) -> tuple:
        x0 = self.cells[0] * self.resolution
        y1 = (self.cells[3] + 1) * self.resolution
        return (x0, self.resolution, 0.0, y1, 0.0, -self.resolution)


@dataclasses.dataclass
class RegionPatch:
    """One changed tile's part of a region raster (Client.query with since).

    rows, cols from (row, col) of the region raster; layers: name -> float32 (rows, cols). A
    tombstone has no layers: every pixel is now unknown (NaN; state 0)."""

    key: tuple  # (x, y)
    row: int
    col: int
    rows: int
    cols: int
    tombstone: bool
    layers: dict


@dataclasses.dataclass
class RegionDelta:
    """What changed in a region since a map version (Client.query with since).

    full: the server could not answer the delta exactly (resync_reason says why) and `region` is
    the whole region; else `patches` hold what changed since (a changed tile's part of the
    region, or rectangles of its changed blocks: several patches may name one tile), `region`
    is None. Ask the next delta with since=map_version, history_id=history_id."""

    full: bool
    resync_reason: str
    region: Optional[Region]
    patches: list
    map_version: int
    history_id: int
    wire_bytes: int

    def apply_to(self, region: Region) -> Region:
        """`region` (an earlier answer of the same query) brought to this answer: patched in
        place and returned, or the full answer."""
        if self.full:
            return self.region
        for p in self.patches:
            window = (slice(p.row, p.row + p.rows), slice(p.col, p.col + p.cols))
            for name, array in region.layers.items():
                if p.tombstone:
                    array[window] = 0.0 if name == "state" else np.nan
                else:
                    array[window] = p.layers[name]
        region.map_version = self.map_version
        region.history_id = self.history_id
        return region


@dataclasses.dataclass
class ExportResult:
    bytes: int        # of the archive file
    tiles: int        # in the archive
    map_version: int  # the archive is the map at exactly this version


@dataclasses.dataclass
class ImportResult:
    tiles_added: int
    map_version: int          # of the import (one change)
    known_cells: int          # of the whole map once the import was done
    archive_map_version: int  # the version the archive was exported at
