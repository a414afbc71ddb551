"""bgkmap.Client: the Python client of bgkmapd (bgkmap.v1.MapService). Numpy in, numpy out.

    import bgkmap
    client = bgkmap.Client("127.0.0.1:50051")
    ack = client.insert(points, pose, robot="r1", seq=1)          # Nx3|Nx4, 4x4
    region = client.query((-20, -20, 20, 20), layers=["traversability"])
    region["traversability"], region.geotransform

Synchronous calls; a Client may be used from several threads at once. Every failure raises
bgkmap.BgkmapError with the gRPC status code and the server's message.
"""

from __future__ import annotations

import collections
import os
import threading
from typing import Callable, Iterable, Iterator, Optional

import grpc
import numpy as np

from bgkmap import _codec
from bgkmap.errors import BgkmapError, invalid_argument, malformed
from bgkmap.results import ExportResult, ImportResult, PathCheck, Region, Scan, ScanAck, TileUpdate
from bgkmap.v1 import admin_pb2, archive_pb2, map_service_pb2_grpc, query_pb2

DEFAULT_SERVER = "127.0.0.1:50051"
_ARCHIVE_CHUNK_BYTES = 1 << 20


def _rpc(call, *args, **kwargs):
    try:
        return call(*args, **kwargs)
    except grpc.RpcError as e:
        raise BgkmapError.from_rpc_error(e) from None


def _read(path: str) -> bytes:
    with open(path, "rb") as f:
        return f.read()


class _CallDetails(collections.namedtuple(
        "_CallDetails", ("method", "timeout", "metadata", "credentials", "wait_for_ready",
                         "compression")), grpc.ClientCallDetails):
    pass


class _BearerToken(grpc.UnaryUnaryClientInterceptor, grpc.UnaryStreamClientInterceptor,
                   grpc.StreamUnaryClientInterceptor, grpc.StreamStreamClientInterceptor):
    """Adds "authorization: Bearer <token>" to every call's metadata."""

    def __init__(self, token: str):
        self._header = ("authorization", "Bearer " + token)

    def _details(self, d):
        metadata = list(d.metadata or []) + [self._header]
        return _CallDetails(d.method, d.timeout, metadata, d.credentials,
                            getattr(d, "wait_for_ready", None), getattr(d, "compression", None))

    def intercept_unary_unary(self, continuation, details, request):
        return continuation(self._details(details), request)

    def intercept_unary_stream(self, continuation, details, request):
        return continuation(self._details(details), request)

    def intercept_stream_unary(self, continuation, details, requests):
        return continuation(self._details(details), requests)

    def intercept_stream_stream(self, continuation, details, requests):
        return continuation(self._details(details), requests)


def _correction(summary) -> dict:
    return {"map_version": summary.map_version, "scans_revised": summary.scans_revised,
            "records_replayed": summary.records_replayed,
            "records_in_history": summary.records_in_history,
            "tiles_changed": summary.tiles_changed, "seconds": summary.seconds}


class Client:
    """A connection to bgkmapd.

    address: "host:port" (any gRPC target); None takes $BGKMAP_SERVER, else 127.0.0.1:50051.
    timeout: deadline in seconds of each call except the long-lived streams (insert_stream, watch);
        None for none.
    tls_ca: path of the CA certificates (PEM) the server's certificate must chain to; set, the
        channel uses TLS (server.tls.cert_file). None: plaintext.
    tls_cert, tls_key: paths of this client's certificate and key (PEM), for a server that asks
        for client certificates (server.tls.client_ca_file).
    tls_server_name: the name the server certificate carries, when not the address's host.
    token: bearer token sent on every call as "authorization: Bearer <token>"
        (server.auth.tokens_file); None takes $BGKMAP_TOKEN, "" sends none.
    credentials: grpc.ChannelCredentials for a TLS channel built by the caller instead of tls_*.
    max_message_bytes: largest message sent or accepted (the server's default limit is 64 MiB).
    options: further gRPC channel arguments, [(name, value), ...].
    compact_step: scans go out compact, quantized to this step in metres, then zstd
        (docs/server.md "Compact scans"; needs python3-zstandard); 0 sends float32 points.
    """

    def __init__(self, address: Optional[str] = None, *, timeout: Optional[float] = 60.0,
                 tls_ca: Optional[str] = None, tls_cert: Optional[str] = None,
                 tls_key: Optional[str] = None, tls_server_name: Optional[str] = None,
                 token: Optional[str] = None,
                 credentials: Optional[grpc.ChannelCredentials] = None,
                 max_message_bytes: int = 64 << 20, options: Iterable = (),
                 compact_step: float = _codec.COMPACT_STEP):
        self.address = address or os.environ.get("BGKMAP_SERVER") or DEFAULT_SERVER
        self.timeout = timeout
        self.compact_step = compact_step
        channel_options = [("grpc.max_receive_message_length", max_message_bytes),
                           ("grpc.max_send_message_length", max_message_bytes)]
        channel_options += list(options)
        if (tls_cert is None) != (tls_key is None):
            raise ValueError("tls_cert and tls_key go together")
        if tls_cert is not None and tls_ca is None:
            raise ValueError("tls_cert needs tls_ca (client certificates need TLS)")
        if tls_ca is not None:
            if credentials is not None:
                raise ValueError("give either tls_ca (and tls_cert, tls_key) or credentials")
            credentials = grpc.ssl_channel_credentials(
                root_certificates=_read(tls_ca),
                private_key=_read(tls_key) if tls_key else None,
                certificate_chain=_read(tls_cert) if tls_cert else None)
        if tls_server_name:
            channel_options.append(("grpc.ssl_target_name_override", tls_server_name))
        if credentials is None:
            self._channel = grpc.insecure_channel(self.address, options=channel_options)
        else:
            self._channel = grpc.secure_channel(self.address, credentials, options=channel_options)
        if token is None:
            token = os.environ.get("BGKMAP_TOKEN", "")
        # Metadata rather than call credentials: a token also works on a plaintext loopback port.
        intercepted = (grpc.intercept_channel(self._channel, _BearerToken(token)) if token
                       else self._channel)
        self._stub = map_service_pb2_grpc.MapServiceStub(intercepted)
        self._limits = None  # (resolution, max_region_cells, max_region_read_cells): Info, once

    # --- lifetime ----------------------------------------------------------------------------

    def close(self) -> None:
        """Closes the channel; running streams end with CANCELLED."""
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"bgkmap.Client({self.address!r})"

    def wait_for_ready(self, timeout: float = 10.0) -> bool:
        """True once the server is reachable (waits at most `timeout` seconds)."""
        ready = grpc.channel_ready_future(self._channel)
        try:
            ready.result(timeout=timeout)
            return True
        except grpc.FutureTimeoutError:
            ready.cancel()
            return False

    # --- scans -------------------------------------------------------------------------------

    def insert(self, points, pose, robot: str, seq: int, stamp=None) -> ScanAck:
        """One scan (unary IngestScan).

        points: Nx3 or Nx4 (x, y, z[, intensity]) in the sensor frame, sent compact (x, y, z
        quantized to compact_step; the map is that of the dequantized points) or as float32;
        NaN or infinite points are dropped and counted in ack.counts.
        pose: T_map_sensor, 4x4 (or 3x4) matrix. robot, seq: robot id and its increasing
        sequence number (an old number is acked "duplicate" and not applied again).
        stamp: seconds since the epoch or an aware datetime; None: now.
        A rejected scan raises BgkmapError (INVALID_ARGUMENT: malformed or over a fixed limit;
        RESOURCE_EXHAUSTED: server load, retry later)."""
        request, left_out = _codec.scan_message(points, pose, robot, seq, stamp,
                                                self.compact_step)
        ack = _codec.ack_from_proto(_rpc(self._stub.IngestScan, request, timeout=self.timeout))
        return _codec.count_left_out(ack, left_out)

    def insert_stream(self, scans: Iterable,
                      on_ack: Optional[Callable[[ScanAck], None]] = None) -> list:
        """Many scans on one Ingest stream, sent as fast as the server's read-ahead allows while
        acks are read concurrently; returns every ack, in send order.

        scans: an iterable (read lazily, may be a generator) of bgkmap.Scan, of dicts with the
        same keys, or of (points, pose, robot, seq[, stamp]) tuples. on_ack is called with each
        ack as it arrives. A bad scan is acked with status "rejected" (code and message say why)
        and the stream goes on. A scan the client cannot encode ends the stream after the scans
        before it: their acks are read, then BgkmapError is raised naming the scan."""
        acks = []
        for ack in self.iter_insert_stream(scans):
            if on_ack is not None:
                on_ack(ack)
            acks.append(ack)
        return acks

    def iter_insert_stream(self, scans: Iterable) -> Iterator[ScanAck]:
        """Like insert_stream, as an iterator of acks in send order (for endless scan sources).
        Scans are sent while the iterator is consumed; leaving it early cancels the stream."""
        problem: list = []
        iterator = iter(scans)
        left_out: dict = {}  # (robot, sequence) -> non-finite points not sent

        def requests():  # runs on gRPC's sending thread: keep exceptions for the caller
            index = 0
            while True:
                try:
                    message, dropped = _scan_to_message(next(iterator), self.compact_step)
                    left_out[(message.robot_id, message.sequence)] = dropped
                except StopIteration:
                    return
                except BgkmapError as e:
                    problem.append(BgkmapError(e.code, f"scan {index}: {e.message}"))
                    return
                except Exception as e:  # raised by the caller's iterable
                    problem.append(e)
                    return
                yield message
                index += 1

        call = self._stub.Ingest(requests())
        try:
            for message in call:
                dropped = left_out.pop((message.robot_id, message.sequence), 0)
                yield _codec.count_left_out(_codec.ack_from_proto(message), dropped)
        except grpc.RpcError as e:
            raise BgkmapError.from_rpc_error(e) from None
        finally:
            call.cancel()  # no-op once the stream ended; stops it if the caller stopped iterating
        if problem:
            raise problem[0]

    def last_sequence(self, robot: str) -> Optional[int]:
        """The last sequence number the server admitted for `robot` (None: none yet), to resume."""
        for r in self.info()["robots"]:
            if r["robot_id"] == robot:
                return r["last_sequence"]
        return None

    # --- queries -----------------------------------------------------------------------------

    def query(self, bbox, layers=None, stride: int = 1, *, since: Optional[int] = None,
              history_id: int = 0, compress: bool = False):
        """Layers over the cells meeting the half-open box (xmin, ymin, xmax, ymax), metres.

        layers: names ("elevation", "elevation_variance", "traversability",
        "traversability_variance", "state", "elevation_weight", "disagreement", "block_reason") or
        None for every layer.
        stride: map cells per pixel edge. Returns a Region: a mapping from layer name to a float32
        (rows, cols) array, rows north to south, NaN = unknown, plus region.geotransform,
        region.map_version and region.history_id.

        A box of more output pixels than the server's max_region_cells (or more map cells than
        its max_region_read_cells) is read in pieces of whole pixel blocks and stitched; each
        piece is one consistent read, but pieces may see different map versions
        (region.map_version is the newest).

        since: a map version (an earlier answer's region.map_version, with its region.history_id
        as history_id) asks only what changed after it, and returns a RegionDelta: the
        patches (changed tiles, or their changed blocks) and tombstones, or the whole region
        when the server cannot answer the delta exactly (delta.full; docs/server.md, "Region
        deltas"). delta.apply_to(region) brings the earlier answer up to date; MapMirror does
        all of this. A box that needs pieces cannot be asked a delta (INVALID_ARGUMENT).

        compress: the server gzips the answer's messages on the wire (RegionRequest.compress;
        decompressed here transparently): far fewer bytes for sparse regions, more server CPU."""
        if int(stride) < 1:
            raise invalid_argument(f"stride: {stride} must be >= 1")
        stride = int(stride)
        resolution, pixels, read = self._region_limit()
        budget = _codec.region_cell_budget(pixels, read, stride)
        pieces = _codec.split_region(bbox, resolution, stride, budget)
        if since is not None:
            if int(since) < 0:
                raise invalid_argument(f"since: {since} must be a map version >= 0")
            if len(pieces) != 1:
                raise invalid_argument(
                    f"since: the box needs {len(pieces)} pieces over the server's "
                    f"max_region_cells = {pixels} pixels; ask a delta of each piece's box")
            return self._query_piece(bbox, layers, stride, since, history_id, compress).delta()
        if len(pieces) == 1:
            return self._query_piece(bbox, layers, stride, compress=compress).region()
        return _codec.stitch_regions([self._query_piece(p, layers, stride, compress=compress)
                                      .region() for p in pieces])

    def _region_limit(self) -> tuple:
        """The map's resolution, the server's max_region_cells and max_region_read_cells (0
        from an older server), asked once."""
        if self._limits is None:
            info = self.info()
            limits = info["limits"]
            self._limits = (info["params"]["resolution"], limits["max_region_cells"],
                            limits.get("max_region_read_cells", 0))
        return self._limits

    def _query_piece(self, bbox, layers, stride: int, since: Optional[int] = None,
                     history_id: int = 0, compress: bool = False) -> _codec.RegionAssembler:
        request = query_pb2.RegionRequest(stride=stride, compress=bool(compress))
        if since is not None:
            request.since_version = int(since)
            request.since_history_id = int(history_id)
        _codec.set_box(bbox, request.box)
        request.layers.extend(_codec.layer_numbers(layers))
        call = self._stub.QueryRegion(request, timeout=self.timeout)
        assembler = _codec.RegionAssembler()
        try:
            for chunk in call:
                assembler.add(chunk)
        except grpc.RpcError as e:
            raise BgkmapError.from_rpc_error(e) from None
        except BgkmapError:
            call.cancel()
            raise
        return assembler

    def points(self, xy, layers=None) -> np.ndarray:
        """Layers at map points: xy is Nx2 (or one (x, y)). Returns a structured array with fields
        x, y and one float32 field per layer (NaN = unknown; state 0)."""
        xy = _codec.xy_array(xy, "xy")
        request = _codec.points_request(xy, layers)
        response = _rpc(self._stub.QueryPoints, request, timeout=self.timeout)
        return _codec.points_from_proto(xy, response)

    def check_path(self, poses, radius: Optional[float] = None, *, polygon=None,
                   max_traversability: Optional[float] = None,
                   max_traversability_variance: Optional[float] = None,
                   max_unknown_fraction: Optional[float] = None) -> PathCheck:
        """Footprint safety along a path: at the poses and along the straight segments between
        consecutive poses (the footprint placed at most a cell apart, heading interpolated).
        poses: Nx3 (x, y, yaw) or Nx2 (yaw 0); footprint: a disk of `radius` or a `polygon`
        [(x, y), ...] in the robot frame (x forward, y left). Unset thresholds take the map's
        trav_threshold, variance_threshold and 0. A placement is safe when its worst
        traversability and variance are below them and its unknown fraction at most
        max_unknown_fraction, so a footprint on unknown ground is unsafe. The answer names the
        first unsafe point (PathCheck.first_unsafe_point)."""
        poses = _codec.xy_array(poses, "poses", columns=(2, 3))
        request = _codec.path_request(poses, radius, polygon, max_traversability,
                                      max_traversability_variance, max_unknown_fraction)
        response = _rpc(self._stub.CheckPath, request, timeout=self.timeout)
        return _codec.path_from_proto(poses, response)

    def watch(self, bbox, layers=None, initial_snapshot: bool = False) -> "Watch":
        """Changed tiles of the tiles meeting the box, as they change: an iterator of TileUpdate
        (coalesced per tile). initial_snapshot sends every existing tile of the region first.
        Ends when cancelled (watch.cancel(), from any thread, or leaving a `with` block); other
        ends raise BgkmapError (UNAVAILABLE on server shutdown)."""
        request = admin_pb2.WatchRequest(initial_snapshot=bool(initial_snapshot))
        _codec.set_box(bbox, request.box)
        request.layers.extend(_codec.layer_numbers(layers))
        return Watch(self._stub.Watch(request))

    def info(self) -> dict:
        """Parameters, tile and known-cell counts, bounds, map version, robots, limits, storage, as
        a dict named like the InfoResponse fields (known_bounds None when the map is empty;
        storage None for a map in memory)."""
        response = _rpc(self._stub.Info, admin_pb2.InfoRequest(), timeout=self.timeout)
        return _codec.info_from_proto(response)

    # --- administration ----------------------------------------------------------------------

    def clear(self, bbox) -> dict:
        """Admin: forgets every cell of the box. Returns changed_tiles and the clear's map_version."""
        request = admin_pb2.ClearRegionRequest()
        _codec.set_box(bbox, request.box)
        r = _rpc(self._stub.ClearRegion, request, timeout=self.timeout)
        return {"changed_tiles": [(k.x, k.y) for k in r.changed_tiles],
                "map_version": r.map_version}

    def correct_poses(self, robot: str, poses) -> dict:
        """The robot's SLAM revised its trajectory: re-integrates its scans with corrected poses.

        poses: {sequence: 4x4 (or 3x4) T_map_sensor} or an iterable of (sequence, pose) pairs.
        Returns once the corrected map is in place: map_version, scans_revised, records_replayed,
        records_in_history, tiles_changed, seconds. FAILED_PRECONDITION if a scan is no longer
        retained (storage.retention_mb)."""
        request = admin_pb2.CorrectPosesRequest(robot_id=robot)
        items = poses.items() if hasattr(poses, "items") else poses
        for sequence, pose in items:
            c = request.corrections.add(sequence=int(sequence))
            _codec.set_pose(pose, c.pose)
        r = _rpc(self._stub.CorrectPoses, request, timeout=self.timeout)
        return _correction(r.summary)

    def remove_scans(self, robot: str, first: int, last: int) -> dict:
        """Removes the robot's scans first..last (inclusive) from the map, as if never sent."""
        request = admin_pb2.RemoveScansRequest(robot_id=robot, first_sequence=int(first),
                                               last_sequence=int(last))
        r = _rpc(self._stub.RemoveScans, request, timeout=self.timeout)
        return _correction(r.summary)

    def export_map(self, path, bbox=None) -> ExportResult:
        """Admin: the map, or the cells meeting `bbox`, as one archive file at `path` (a consistent
        snapshot at one map version). Written to path + ".partial", synced, then renamed: `path`
        is either the complete archive or untouched."""
        path = os.fspath(path)
        request = archive_pb2.ExportRequest()
        if bbox is not None:
            _codec.set_box(bbox, request.box)
        partial = path + ".partial"
        try:
            out = open(partial, "wb")
        except OSError as e:
            raise invalid_argument(f"cannot create {partial}: {e.strerror}") from None
        done = False
        try:
            with out:
                result = self._receive_archive(request, out, partial)
                out.flush()
                os.fsync(out.fileno())
            try:
                os.replace(partial, path)
            except OSError as e:
                raise invalid_argument(f"cannot rename to {path}: {e.strerror}") from None
            done = True
            return result
        finally:
            if not done:
                try:
                    os.remove(partial)
                except OSError:
                    pass

    def _receive_archive(self, request, out, partial: str) -> ExportResult:
        call = self._stub.ExportMap(request, timeout=self.timeout)
        result = ExportResult(bytes=0, tiles=0, map_version=0)
        first, last = True, False
        try:
            for chunk in call:
                if first:
                    result.map_version = chunk.map_version
                    first = False
                if last:
                    call.cancel()
                    raise malformed("archive chunk after the last one")
                try:
                    out.write(chunk.data)
                except OSError as e:
                    call.cancel()
                    raise invalid_argument(f"writing {partial}: {e.strerror}") from None
                result.bytes += len(chunk.data)
                if chunk.last:
                    last = True
                    result.tiles = chunk.tiles
        except grpc.RpcError as e:
            raise BgkmapError.from_rpc_error(e) from None
        if not last:
            raise malformed("archive stream ended before its last chunk")
        return result

    def import_map(self, path) -> ImportResult:
        """Admin: adds the archive at `path` into the served map (statistics are summed, so importing
        two robots' archives gives exactly their sum). Nothing changes unless the whole archive
        verifies: INVALID_ARGUMENT (not an archive), DATA_LOSS (damaged), FAILED_PRECONDITION
        (incompatible parameters or georeference), INVALID_ARGUMENT (too large, not an archive),
        RESOURCE_EXHAUSTED (another import running)."""
        path = os.fspath(path)
        try:
            f = open(path, "rb")
        except OSError as e:
            raise invalid_argument(f"cannot open {path}: {e.strerror}") from None
        problem: list = []

        def chunks():
            with f:
                while True:
                    try:
                        data = f.read(_ARCHIVE_CHUNK_BYTES)
                    except OSError as e:
                        problem.append(invalid_argument(f"reading {path}: {e.strerror}"))
                        return
                    if not data:
                        return
                    yield archive_pb2.ArchiveChunk(data=data)

        try:
            r = self._stub.ImportMap(chunks(), timeout=self.timeout)
        except grpc.RpcError as e:
            if problem:
                raise problem[0] from None
            raise BgkmapError.from_rpc_error(e) from None
        if problem:  # a short read ended the upload early; the server may have taken it as whole
            raise problem[0]
        return ImportResult(tiles_added=r.tiles_added, map_version=r.map_version,
                            known_cells=r.known_cells, archive_map_version=r.archive_map_version)

    # Short names: export is not a keyword, import is.
    export = export_map
    import_ = import_map


def _scan_to_message(scan, compact_step: float):
    if isinstance(scan, Scan):
        return _codec.scan_message(scan.points, scan.pose, scan.robot, scan.seq, scan.stamp,
                                   compact_step)
    if isinstance(scan, dict):
        try:
            return _codec.scan_message(scan["points"], scan["pose"], scan["robot"], scan["seq"],
                                       scan.get("stamp"), compact_step)
        except KeyError as e:
            raise invalid_argument(f"missing key {e.args[0]!r} (points, pose, robot, seq)") from None
    if isinstance(scan, (tuple, list)) and len(scan) in (4, 5):
        points, pose, robot, seq = scan[:4]
        stamp = scan[4] if len(scan) == 5 else None
        return _codec.scan_message(points, pose, robot, seq, stamp, compact_step)
    raise invalid_argument(
        f"expected a bgkmap.Scan, a dict or a (points, pose, robot, seq[, stamp]) tuple, "
        f"got {type(scan).__name__}")


class Watch:
    """A running Watch: iterate it for TileUpdates; cancel() (any thread) ends the iteration."""

    def __init__(self, call):
        self._call = call
        self._cancelled = threading.Event()

    def __iter__(self) -> "Watch":
        return self

    def __next__(self) -> TileUpdate:
        if self._cancelled.is_set():
            raise StopIteration
        try:
            message = next(self._call)
        except StopIteration:
            raise
        except grpc.RpcError as e:
            if self._cancelled.is_set() and e.code() == grpc.StatusCode.CANCELLED:
                raise StopIteration from None
            raise BgkmapError.from_rpc_error(e) from None
        return _codec.tile_update_from_proto(message)

    def cancel(self) -> None:
        self._cancelled.set()
        self._call.cancel()

    def __enter__(self) -> "Watch":
        return self

    def __exit__(self, *exc) -> None:
        self.cancel()
