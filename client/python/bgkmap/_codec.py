"""numpy <-> bgkmap.v1 messages, the same mapping as the C++ client (client/src/proto_codec.cc and
proto/codec/): packed little-endian float32 layers, rows north to south, NaN = unknown."""

from __future__ import annotations

import datetime
import math
import threading
import time
from typing import Iterable, Optional, Sequence

import numpy as np

from bgkmap.errors import invalid_argument, malformed, status_code
from bgkmap.results import PathCheck, Region, RegionDelta, RegionPatch, ScanAck, TileUpdate
from bgkmap.v1 import admin_pb2, ingest_pb2, query_pb2, types_pb2

_LAYER_PREFIX = "LAYER_"

# Layer names, in the API's numbering ("elevation", ..., "block_reason").
LAYERS = tuple(
    v.name[len(_LAYER_PREFIX):].lower()
    for v in sorted(types_pb2.Layer.DESCRIPTOR.values, key=lambda v: v.number)
    if v.number != 0)


def _ack_status(value: int) -> str:
    """AckStatus -> "applied", "duplicate" or "rejected" (by the value's name's last word)."""
    try:
        name = ingest_pb2.AckStatus.Name(value)
    except ValueError:
        return "rejected"
    for status in ("applied", "duplicate"):
        if name.endswith("_" + status.upper()):
            return status
    return "rejected"


_F32 = np.dtype("<f4")

# How far a pose's 3x3 block may be from orthonormal (max |R^T R - I|).
ROTATION_TOLERANCE = 1e-3


def layer_number(layer) -> int:
    """A layer name ("traversability") or API number (3) -> the API number."""
    if isinstance(layer, str):
        try:
            return types_pb2.Layer.Value(_LAYER_PREFIX + layer.upper())
        except ValueError:
            raise invalid_argument(
                f"layer '{layer}': must be one of {', '.join(LAYERS)}") from None
    if isinstance(layer, (int, np.integer)) and not isinstance(layer, bool):
        return int(layer)
    raise invalid_argument(f"layer {layer!r}: expected a layer name such as 'traversability'")


def layer_name(number: int) -> str:
    try:
        return types_pb2.Layer.Name(number)[len(_LAYER_PREFIX):].lower()
    except ValueError:
        return f"layer_{number}"  # a layer this client is too old to name


def layer_numbers(layers) -> list:
    if layers is None:
        return []
    if isinstance(layers, (str, int)):
        layers = [layers]
    return [layer_number(l) for l in layers]


def set_box(box, out: types_pb2.BoundingBox, what: str = "bbox") -> None:
    """(xmin, ymin, xmax, ymax) -> BoundingBox; the server checks order and limits."""
    try:
        values = [float(v) for v in box]
    except (TypeError, ValueError):
        raise invalid_argument(f"{what}: expected (xmin, ymin, xmax, ymax), got {box!r}") from None
    if len(values) != 4:
        raise invalid_argument(f"{what}: expected (xmin, ymin, xmax, ymax), got {len(values)} numbers")
    out.min_x, out.min_y, out.max_x, out.max_y = values


# --- regions larger than the server's limit ---------------------------------------------------


def _region_cells(box, resolution: float, stride: int):
    """The server's cell box of a half-open metric box (rpc/request_checks.cc, RegionCells):
    edges within a micro-cell of a border snap to it, blocks aligned with the global grid."""
    snap = 1e-6
    x0 = math.floor(box[0] / resolution + snap)
    y0 = math.floor(box[1] / resolution + snap)
    x1 = max(x0, math.ceil(box[2] / resolution - snap) - 1)
    y1 = max(y0, math.ceil(box[3] / resolution - snap) - 1)
    floor_to = lambda a: (a // stride) * stride  # noqa: E731  (Python's // floors)
    return floor_to(x0), floor_to(y0), floor_to(x1) + stride - 1, floor_to(y1) + stride - 1


MAX_REGION_PIECES = 256  # a larger box is sent whole, for the server to refuse by its limit


def region_cell_budget(max_region_cells: int, max_region_read_cells: int, stride: int) -> int:
    """The map cells one region query may read at `stride`: max_region_cells pixels x stride^2,
    within max_region_read_cells; an older server (read cells 0) counted map cells."""
    if not max_region_read_cells:
        return max_region_cells
    return min(max_region_cells * stride * stride, max_region_read_cells)


def split_region(box, resolution: float, stride: int, max_cells: int) -> list:
    """Metric boxes of whole pixel blocks, north-west first, each within max_cells map cells,
    that together cover the cells the server would read for `box`; [box] when it fits, when the
    box is not valid (the server names the problem) or when it would take more than
    MAX_REGION_PIECES pieces (the server then names its limit)."""
    try:
        values = [float(v) for v in box]
    except (TypeError, ValueError):
        return [box]
    if len(values) != 4 or not all(math.isfinite(v) for v in values) or \
            not (values[0] < values[2] and values[1] < values[3]):
        return [box]
    x0, y0, x1, y1 = _region_cells(values, resolution, stride)
    width, height = x1 - x0 + 1, y1 - y0 + 1
    if width * height <= max_cells or max_cells < stride * stride:
        return [box]
    cols = width if width * stride <= max_cells else max(stride, max_cells // stride // stride * stride)
    rows = max(stride, max_cells // cols // stride * stride)
    if -(-height // rows) * -(-width // cols) > MAX_REGION_PIECES:
        return [box]
    pieces = []
    for top in range(y1, y0 - 1, -rows):  # north first
        bottom = max(y0, top - rows + 1)
        for left in range(x0, x1 + 1, cols):
            right = min(x1, left + cols - 1)
            pieces.append((left * resolution, bottom * resolution,
                           (right + 1) * resolution, (top + 1) * resolution))
    return pieces


def stitch_regions(pieces: list) -> Region:
    """One Region from pieces of the same stride that tile a box of cells."""
    stride = pieces[0].stride
    min_x = min(p.cells[0] for p in pieces)
    min_y = min(p.cells[1] for p in pieces)
    max_x = max(p.cells[2] for p in pieces)
    max_y = max(p.cells[3] for p in pieces)
    rows, cols = (max_y - min_y + 1) // stride, (max_x - min_x + 1) // stride
    layers = {name: np.empty((rows, cols), dtype=_F32) for name in pieces[0].layers}
    for p in pieces:
        r, c = (max_y - p.cells[3]) // stride, (p.cells[0] - min_x) // stride
        for name, values in p.layers.items():
            layers[name][r:r + p.rows, c:c + p.cols] = values
    first = pieces[0]  # the north-west piece: its corner is the region's
    return Region(layers, x0=first.x0, y1=first.y1, resolution=first.resolution, stride=stride,
                  cells=(min_x, min_y, max_x, max_y),
                  map_version=max(p.map_version for p in pieces))


# --- scans -----------------------------------------------------------------------------------


def pack_points(points) -> bytes:
    """Nx3 or Nx4 (x, y, z[, intensity]) -> packed little-endian float32 x, y, z."""
    array = np.asarray(points)
    if array.ndim != 2 or array.shape[1] not in (3, 4):
        raise invalid_argument(f"points: expected an Nx3 or Nx4 array, got shape {array.shape}")
    if not np.issubdtype(array.dtype, np.number):
        raise invalid_argument(f"points: expected numbers, got dtype {array.dtype}")
    return np.ascontiguousarray(array[:, :3], dtype=_F32).tobytes()


# The compact point encoding (docs/server.md "Compact scans"), the C++ codec's orders in the order
# sent (proto/codec/include/bgkmap/proto/compact_points.h). Needs Debian's python3-zstandard; without
# it scans go as float32, which the server accepts as well.
try:
    import zstandard as _zstd
except ImportError:  # pragma: no cover - install-deps installs it
    _zstd = None

COMPACT_STEP = 0.002  # metres, as the C++ client
_SCAN_ORDER_LIMIT = 1 << 30
# zstd level 1, as the C++ codec: on the real sweeps as small as level 3 within ~1 %, and cheaper.
_ZSTD_LEVEL = 1
_compressors = threading.local()


def _compressor():
    """One compressor per thread, kept (a ZstdCompressor is not safe to share between threads, and
    a fresh one per scan costs its tables' allocation)."""
    c = getattr(_compressors, "c", None)
    if c is None or _compressors.level != _ZSTD_LEVEL:
        c = _compressors.c = _zstd.ZstdCompressor(level=_ZSTD_LEVEL)
        _compressors.level = _ZSTD_LEVEL
    return c


def _divide_rounded(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a / b rounded half away from zero in integers (b != 0), as the C++ codec: C's truncating
    division of a +- floor(|b| / 2) by b."""
    num = a + np.where(a >= 0, 1, -1) * (np.abs(b) // 2)
    return np.where((num >= 0) == (b > 0), 1, -1) * (np.abs(num) // np.abs(b))


def _ray_residuals(q: np.ndarray) -> Optional[np.ndarray]:
    """POINT_ORDER_SCAN_RAY's residuals (compact_points.h has the rule): each point predicted
    from the two before it, the error off the previous point's ray predicted from the error on
    that point's largest axis. None if a residual does not fit int32."""
    n = len(q)
    prev = np.zeros_like(q)
    prev[1:] = q[:-1]
    base = 2 * prev
    base[2:] -= q[:-2]
    if n > 1:
        base[1] = q[0]
    e = q - base
    axis = np.argmax(np.abs(prev), axis=1)  # the first of equals, 0 for point 0
    rows = np.arange(n)
    on_axis = e[rows, axis][:, None]
    prev_axis = prev[rows, axis][:, None]
    safe = np.where(prev_axis == 0, 1, prev_axis)
    along = np.where(prev_axis == 0, 0, _divide_rounded(on_axis * prev, safe))
    along[rows, axis] = 0
    r = e - along
    if r.size and (r.min() < -(1 << 31) or r.max() >= (1 << 31)):
        return None
    return r


def compact_points(points, step: float, out: ingest_pb2.CompactPoints) -> Optional[int]:
    """Quantizes Nx3|Nx4 points to `step` and fills `out` in the order sent: along the rays
    (POINT_ORDER_SCAN_RAY) or, where those residuals overflow, as plain differences
    (POINT_ORDER_SCAN); zigzagged int32 as 12 byte planes (byte b of axis c for every point, b
    outer, c inner), then zstd. Returns how many non-finite points were left out (the server drops
    them anyway), or None if a point has no quantized value (|q| >= 2^30) or zstd is missing:
    then the points must go as float32."""
    if _zstd is None:
        return None
    xyz = np.asarray(points)[:, :3].astype(_F32).astype(np.float64)
    finite = np.all(np.isfinite(xyz), axis=1)
    # Any integer is a valid quantum: the server integrates float32(q * step), whatever q is.
    q = np.round(xyz[finite] / step)
    if q.size and np.max(np.abs(q)) >= _SCAN_ORDER_LIMIT:
        return None
    q = q.astype(np.int64)
    d = _ray_residuals(q)
    out.order = ingest_pb2.POINT_ORDER_SCAN_RAY
    if d is None:
        d = np.diff(q, axis=0, prepend=np.zeros((1, 3), dtype=np.int64))
        out.order = ingest_pb2.POINT_ORDER_SCAN
    z = ((d << 1) ^ (d >> 63)).astype("<u4")
    planes = z.view(np.uint8).reshape(len(z), 3, 4).transpose(2, 1, 0)
    out.step = step
    out.count = len(z)
    out.data = _compressor().compress(np.ascontiguousarray(planes).tobytes())
    return int(np.count_nonzero(~finite))


def quaternion_from_matrix(r: np.ndarray) -> tuple:
    """A 3x3 rotation matrix -> unit quaternion (w, x, y, z), as Eigen's conversion the C++ client
    uses (ScanPose::FromPose)."""
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    if trace > 0:
        s = math.sqrt(trace + 1.0) * 2.0
        w, x, y, z = 0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2.0
        w, x, y, z = (r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s
    elif r[1, 1] > r[2, 2]:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2.0
        w, x, y, z = (r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s
    else:
        s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2.0
        w, x, y, z = (r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if norm > 0 and math.isfinite(norm):
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return float(w), float(x), float(y), float(z)


def set_pose(pose, out: types_pb2.Pose3) -> None:
    """A 4x4 or 3x4 T_map_sensor -> Pose3 (translation and unit quaternion). A finite 3x3 block
    must be a rotation; a non-finite pose is sent as it is and the server names the field."""
    matrix = np.asarray(pose, dtype=np.float64)
    if matrix.shape not in ((4, 4), (3, 4)):
        raise invalid_argument(f"pose: expected a 4x4 (or 3x4) matrix, got shape {matrix.shape}")
    rotation = matrix[:3, :3]
    if np.all(np.isfinite(rotation)):
        error = float(np.max(np.abs(rotation.T @ rotation - np.eye(3))))
        if error > ROTATION_TOLERANCE or np.linalg.det(rotation) <= 0:
            raise invalid_argument(
                f"pose: the 3x3 block is not a rotation (max |R^T R - I| = {error:.3g}, "
                f"det = {np.linalg.det(rotation):.3g})")
        w, x, y, z = quaternion_from_matrix(rotation)
    else:
        w = x = y = z = math.nan
    out.translation.x, out.translation.y, out.translation.z = (float(v) for v in matrix[:3, 3])
    out.rotation.w, out.rotation.x, out.rotation.y, out.rotation.z = w, x, y, z


def _stamp_ns(stamp) -> int:
    if stamp is None:
        return time.time_ns()
    if isinstance(stamp, datetime.datetime):
        if stamp.tzinfo is None:
            raise invalid_argument("stamp: a naive datetime is ambiguous; give it a tzinfo")
        return int(round(stamp.timestamp() * 1e9))
    try:
        seconds = float(stamp)
    except (TypeError, ValueError):
        raise invalid_argument(f"stamp: expected seconds since the epoch or a datetime, got {stamp!r}") from None
    if not math.isfinite(seconds) or seconds < 0:
        raise invalid_argument(f"stamp: {seconds} is not a time since the epoch")
    return int(round(seconds * 1e9))


def scan_message(points, pose, robot: str, seq: int, stamp=None,
                 compact_step: float = COMPACT_STEP) -> tuple:
    """(the Scan message, how many non-finite points it left out). compact_step 0: float32."""
    scan = ingest_pb2.Scan()
    if not isinstance(robot, str):
        raise invalid_argument(f"robot: expected a string, got {type(robot).__name__}")
    scan.robot_id = robot
    try:
        sequence = int(seq)
    except (TypeError, ValueError):
        raise invalid_argument(f"seq: expected an integer, got {seq!r}") from None
    if sequence < 0:
        raise invalid_argument(f"seq: {sequence} is negative")
    scan.sequence = sequence
    ns = _stamp_ns(stamp)
    scan.stamp.seconds, scan.stamp.nanos = divmod(ns, 1_000_000_000)
    set_pose(pose, scan.pose)
    packed = pack_points(points)  # checks the shape and type
    if compact_step > 0:
        left_out = compact_points(np.frombuffer(packed, dtype=_F32).reshape(-1, 3), compact_step,
                                  scan.compact_points)
        if left_out is not None:
            return scan, left_out
        scan.ClearField("compact_points")
    scan.points = packed
    return scan, 0


def count_left_out(ack: ScanAck, nonfinite: int) -> ScanAck:
    """The ack's counts as if the non-finite points left out had been sent."""
    if nonfinite and ack.status == "applied":
        ack.counts["input"] += nonfinite
        ack.counts["dropped_nonfinite"] += nonfinite
    return ack


def ack_from_proto(a: ingest_pb2.ScanAck) -> ScanAck:
    return ScanAck(
        robot_id=a.robot_id,
        sequence=a.sequence,
        status=_ack_status(a.status),
        code=status_code(a.code),
        message=a.message,
        changed_tiles=[(k.x, k.y) for k in a.changed_tiles],
        map_version=a.map_version,
        counts={f.name: getattr(a.counts, f.name) for f in a.counts.DESCRIPTOR.fields})


# --- regions and tiles -----------------------------------------------------------------------


class RegionAssembler:
    """Assembles a region answer from its chunks, checking them as the C++ client does: the whole
    region as rows, or a delta's patches (docs/server.md, "Region deltas")."""

    def __init__(self):
        self.header = None
        self.arrays = None
        self.patches = []
        self.next_row = 0
        self.wire_bytes = 0

    @property
    def is_delta(self) -> bool:
        return self.header is not None and self.header.answer == query_pb2.REGION_ANSWER_DELTA

    def add(self, chunk: query_pb2.RegionChunk) -> None:
        self.wire_bytes += chunk.ByteSize()
        if chunk.HasField("header"):
            if self.header is not None:
                raise malformed("region answer with two headers")
            h = chunk.header
            self.header = h
            if not self.is_delta:
                self.arrays = [np.empty((h.rows, h.cols), dtype=np.float32) for _ in h.layers]
        h = self.header
        if h is None:
            raise malformed("region chunk before the header")
        if self.is_delta:
            if chunk.row_count or len(chunk.layers):
                raise malformed("region delta with rows")
            for p in chunk.patches:
                self.patches.append(self._patch(p))
            return
        if (len(chunk.patches) or chunk.row_start != self.next_row
                or len(chunk.layers) != len(h.layers) or self.next_row + chunk.row_count > h.rows):
            raise malformed("region chunk out of order")
        expect = chunk.row_count * h.cols * 4
        for array, values in zip(self.arrays, chunk.layers):
            if len(values.values) != expect:
                raise malformed("region chunk of the wrong size")
            rows = np.frombuffer(values.values, dtype=_F32).reshape(chunk.row_count, h.cols)
            array[self.next_row:self.next_row + chunk.row_count] = rows
        self.next_row += chunk.row_count

    def _patch(self, p: query_pb2.TilePatch) -> RegionPatch:
        h = self.header
        if p.row_start + p.rows > h.rows or p.col_start + p.cols > h.cols:
            raise malformed("region patch outside the region")
        layers = {}
        if p.tombstone:
            if len(p.layers):
                raise malformed("region tombstone with values")
        else:
            if [lv.layer for lv in p.layers] != list(h.layers):
                raise malformed("region patch with the wrong layers")
            for lv in p.layers:
                if len(lv.values) != p.rows * p.cols * 4:
                    raise malformed("region patch of the wrong size")
                layers[layer_name(lv.layer)] = np.frombuffer(
                    lv.values, dtype=_F32).reshape(p.rows, p.cols)
        return RegionPatch(key=(p.key.x, p.key.y), row=p.row_start, col=p.col_start, rows=p.rows,
                           cols=p.cols, tombstone=p.tombstone, layers=layers)

    def region(self) -> Region:
        h = self.header
        if h is None or self.is_delta or self.next_row != h.rows:
            raise malformed("region stream incomplete")
        layers = {layer_name(l): a for l, a in zip(h.layers, self.arrays)}
        return Region(layers, x0=h.x0, y1=h.y1, resolution=h.resolution, stride=h.stride,
                      cells=(h.cells.min_x, h.cells.min_y, h.cells.max_x, h.cells.max_y),
                      map_version=h.map_version, history_id=h.history_id,
                      wire_bytes=self.wire_bytes)

    def delta(self) -> RegionDelta:
        h = self.header
        if h is None:
            raise malformed("region stream incomplete")
        full = not self.is_delta
        return RegionDelta(full=full, resync_reason=h.resync_reason,
                           region=self.region() if full else None,
                           patches=self.patches, map_version=h.map_version,
                           history_id=h.history_id, wire_bytes=self.wire_bytes)


def tile_update_from_proto(m: admin_pb2.TileUpdate) -> TileUpdate:
    cols = m.cells.max_x - m.cells.min_x + 1
    rows = m.cells.max_y - m.cells.min_y + 1
    layers = {}
    for lv in m.layers:
        if len(lv.values) != rows * cols * 4:
            raise malformed(f"tile ({m.key.x}, {m.key.y}): layer of the wrong size")
        layers[layer_name(lv.layer)] = np.frombuffer(lv.values, dtype=_F32).reshape(rows, cols).copy()
    return TileUpdate(key=(m.key.x, m.key.y), tile_version=m.tile_version,
                      map_version=m.map_version,
                      cells=(m.cells.min_x, m.cells.min_y, m.cells.max_x, m.cells.max_y),
                      resolution=m.resolution, layers=layers)


# --- points and paths ------------------------------------------------------------------------


def xy_array(xy, what: str, columns: Sequence[int] = (2,)) -> np.ndarray:
    array = np.asarray(xy, dtype=np.float64)
    if array.ndim == 1 and array.shape[0] in columns:
        array = array[np.newaxis, :]
    if array.ndim != 2 or array.shape[1] not in columns:
        shapes = " or ".join(f"Nx{c}" for c in columns)
        raise invalid_argument(f"{what}: expected an {shapes} array, got shape {np.shape(xy)}")
    return array


def points_request(xy: np.ndarray, layers) -> query_pb2.PointsRequest:
    request = query_pb2.PointsRequest()
    for x, y in xy:
        p = request.points.add()
        p.x, p.y = float(x), float(y)
    request.layers.extend(layer_numbers(layers))
    return request


def points_from_proto(xy: np.ndarray, r: query_pb2.PointsResponse) -> np.ndarray:
    names = [layer_name(l) for l in r.layers]
    if len(r.values) != len(xy) * len(names):
        raise malformed("point values do not match the request")
    out = np.zeros(len(xy), dtype=[("x", "f8"), ("y", "f8")] + [(n, "f4") for n in names])
    out["x"] = xy[:, 0]
    out["y"] = xy[:, 1]
    values = np.array(r.values, dtype=np.float32).reshape(len(xy), len(names))
    for j, n in enumerate(names):
        out[n] = values[:, j]
    return out


def path_request(poses: np.ndarray, radius, polygon, max_traversability,
                 max_traversability_variance, max_unknown_fraction) -> query_pb2.PathCheckRequest:
    request = query_pb2.PathCheckRequest()
    for pose in poses:
        p = request.poses.add()
        p.x, p.y = float(pose[0]), float(pose[1])
        p.yaw = float(pose[2]) if len(pose) > 2 else 0.0
    if (radius is None) == (polygon is None):
        raise invalid_argument("give one footprint: radius=R or polygon=[(x, y), ...]")
    if polygon is not None:
        for x, y in xy_array(polygon, "polygon"):
            v = request.polygon.vertices.add()
            v.x, v.y = float(x), float(y)
    else:
        request.radius = float(radius)
    if max_traversability is not None:
        request.max_traversability = float(max_traversability)
    if max_traversability_variance is not None:
        request.max_traversability_variance = float(max_traversability_variance)
    if max_unknown_fraction is not None:
        request.max_unknown_fraction = float(max_unknown_fraction)
    return request


_POSE_CHECK_DTYPE = np.dtype([
    ("x", "f8"), ("y", "f8"), ("yaw", "f8"), ("worst_traversability", "f4"),
    ("worst_traversability_variance", "f4"), ("unknown_fraction", "f4"), ("cell_count", "u4"),
    ("safe", "?")])


def path_from_proto(poses: np.ndarray, r: query_pb2.PathCheckResponse) -> PathCheck:
    if len(r.poses) != len(poses):
        raise malformed("path check does not match the request")
    out = np.zeros(len(poses), dtype=_POSE_CHECK_DTYPE)
    out["x"] = poses[:, 0]
    out["y"] = poses[:, 1]
    out["yaw"] = poses[:, 2] if poses.shape[1] > 2 else 0.0
    for name in ("worst_traversability", "worst_traversability_variance", "unknown_fraction",
                 "cell_count", "safe"):
        out[name] = [getattr(c, name) for c in r.poses]
    if len(r.segments) != max(len(poses) - 1, 0):
        raise malformed("path check does not match the request")
    segments = np.zeros(len(r.segments), dtype=_SEGMENT_CHECK_DTYPE)
    segments["safe"] = [s.safe for s in r.segments]
    segments["placement_count"] = [s.placement_count for s in r.segments]
    first = None if r.safe else int(r.first_unsafe_index)
    point = _path_point(r.first_unsafe_point) if r.HasField("first_unsafe_point") else None
    return PathCheck(safe=r.safe, first_unsafe_index=first, poses=out, map_version=r.map_version,
                     segments=segments, first_unsafe_point=point)


_SEGMENT_CHECK_DTYPE = np.dtype([("safe", "?"), ("placement_count", "u4")])


def _path_point(p: query_pb2.PathPoint) -> dict:
    """A PathPoint as a dict: x, y, yaw, segment, t and its footprint's verdict."""
    c = p.check
    return {"x": p.x, "y": p.y, "yaw": p.yaw, "segment": int(p.segment), "t": p.t,
            "worst_traversability": c.worst_traversability,
            "worst_traversability_variance": c.worst_traversability_variance,
            "unknown_fraction": c.unknown_fraction, "cell_count": int(c.cell_count),
            "safe": c.safe}


# --- info ------------------------------------------------------------------------------------


def message_to_dict(message) -> dict:
    """A message as plain Python values: numbers stay numbers (64-bit ones too), enums become their
    names, a Timestamp seconds since the epoch (float), an unset message None."""
    out = {}
    for field in message.DESCRIPTOR.fields:
        value = getattr(message, field.name)
        if field.label == field.LABEL_REPEATED:
            out[field.name] = [_value(field, v) for v in value]
        elif field.message_type is not None and not message.HasField(field.name):
            out[field.name] = None
        else:
            out[field.name] = _value(field, value)
    return out


def _value(field, value):
    if field.message_type is not None:
        if field.message_type.full_name == "google.protobuf.Timestamp":
            return value.seconds + value.nanos * 1e-9
        return message_to_dict(value)
    if field.enum_type is not None:
        number = field.enum_type.values_by_number.get(value)
        return number.name if number is not None else value
    return value


def info_from_proto(r: admin_pb2.InfoResponse) -> dict:
    info = message_to_dict(r)
    if r.known_cells == 0:  # the box is empty and the bounds are zero: say "nothing" instead
        info["known_cells_box"] = None
        info["known_bounds"] = None
    return info
