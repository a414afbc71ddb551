"""bgkmap.Client against a real bgkmapd holding the real Ouster street scans."""

from __future__ import annotations

import json
import os
import subprocess
import threading
import time

import grpc
import numpy as np
import pytest

import bgkmap
from conftest import BgkmapdProcess

LAYERS = ["elevation", "elevation_variance", "traversability", "traversability_variance", "state",
          "disagreement", "block_reason"]


def known_box(info: dict) -> tuple:
    b = info["known_bounds"]
    return (b["min_x"], b["min_y"], b["max_x"], b["max_y"])


def cancel_after(watch: bgkmap.Watch, seconds: float) -> threading.Timer:
    """Bounds a test's wait on a watch: cancelled after `seconds`, its iteration ends."""
    timer = threading.Timer(seconds, watch.cancel)
    timer.daemon = True
    timer.start()
    return timer


def assert_same(a: np.ndarray, b: np.ndarray) -> None:
    """Equal values, NaN where the other has NaN."""
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_array_equal(a[~np.isnan(a)], b[~np.isnan(b)])


# --- insert ----------------------------------------------------------------------------------


def test_info_describes_the_street_map(client, street):
    info = client.info()
    assert info["server_version"] == bgkmap.__version__
    assert info["map_version"] == len(street)
    assert info["scans_applied"] == len(street)
    assert info["known_cells"] > 100_000
    assert info["params"]["resolution"] == pytest.approx(0.1)
    assert info["params"]["method"] == "bgk+"
    assert info["params"]["prior_weight"] == 0.0  # YAML key lambda, a Python keyword
    assert "lambda:" in info["params_yaml"]
    assert [r["robot_id"] for r in info["robots"]] == ["street"]
    assert info["robots"][0]["last_sequence"] == len(street)
    assert info["robots"][0]["last_stamp"] > 1.6e9  # seconds since the epoch
    assert info["limits"]["max_region_cells"] > 0
    assert info["storage"] is None  # a map in memory
    assert info["georeference"] is None  # a local frame
    b = info["known_bounds"]
    assert b["min_x"] < b["max_x"] and b["min_y"] < b["max_y"]
    assert client.last_sequence("street") == len(street)
    assert client.last_sequence("nobody") is None


def test_info_shows_the_georeference_the_store_keeps(tmp_path):
    store = str(tmp_path / "store")
    origin = ["--set", "georeference.origin=[551000.5, 4180000.25, 12.5]"]
    first = BgkmapdProcess("--data-dir", store, "--set", "georeference.crs=EPSG:32610", *origin)
    try:
        with first.client() as c:
            geo = c.info()["georeference"]
    finally:
        assert first.stop() == 0
    assert geo == {"crs": "EPSG:32610", "origin_easting": 551000.5,
                   "origin_northing": 4180000.25, "origin_height": 12.5}
    # Restarted with none configured: the store's.
    again = BgkmapdProcess("--data-dir", store)
    try:
        with again.client() as c:
            assert c.info()["georeference"] == geo
    finally:
        assert again.stop() == 0


def test_insert_acks_and_duplicates(fresh_server, street):
    points, pose = street[0]
    with fresh_server.client() as client:
        ack = client.insert(points, pose, robot="r1", seq=5)
        assert ack.ok and ack.status == "applied"
        assert (ack.robot_id, ack.sequence, ack.map_version) == ("r1", 5, 1)
        assert ack.code == grpc.StatusCode.OK and ack.message == ""
        assert ack.changed_tiles == sorted(ack.changed_tiles) and len(ack.changed_tiles) > 0
        counts = ack.counts
        assert counts["input"] == len(points)
        assert counts["kept"] + sum(v for k, v in counts.items()
                                    if k.startswith("dropped_")) == counts["input"]
        # The same number again is a duplicate, not applied twice; an Nx3 float64 array works too.
        again = client.insert(points[:, :3].astype(np.float64), pose, robot="r1", seq=5)
        assert again.status == "duplicate" and again.map_version == 1
        # NaN points are dropped and counted, not an error.
        with_nan = points.copy()
        with_nan[:10, 0] = np.nan
        ack = client.insert(with_nan, pose, robot="r1", seq=6)
        assert ack.status == "applied" and ack.counts["dropped_nonfinite"] == 10
        assert client.wait_for_ready(10)
        # Clear forgets a box: its cells become unknown, the rest stays.
        assert client.points([(10.0, 0.0), (5.0, -3.0)], layers=["state"])["state"].all()
        cleared = client.clear((9, -1, 11, 1))
        assert cleared["map_version"] == 3 and (1, -1) in cleared["changed_tiles"]
        state = client.points([(10.0, 0.0), (5.0, -3.0)], layers=["state"])["state"]
        assert state[0] == 0 and state[1] != 0


def test_insert_stream_acks_in_order_and_goes_on_after_a_rejected_scan(fresh_server, street):
    scans = [bgkmap.Scan(points, pose, robot="r2", seq=k + 1) for k, (points, pose) in
             enumerate(street)]
    with fresh_server.client() as client:
        seen = []
        acks = client.insert_stream(iter(scans), on_ack=seen.append)
        assert [a.sequence for a in acks] == [1, 2, 3]
        assert [a.status for a in acks] == ["applied"] * 3
        assert seen == acks
        assert [a.map_version for a in acks] == [1, 2, 3]
        # Sent again: duplicates. Tuples and dicts are scans too.
        points, pose = street[0]
        again = client.insert_stream([(points, pose, "r2", 1),
                                      {"points": points, "pose": pose, "robot": "r2", "seq": 2}])
        assert [a.status for a in again] == ["duplicate", "duplicate"]
        # A scan the server refuses is acked "rejected" with its status; the stream goes on.
        acks = client.insert_stream([(points, pose, "", 1), (points, pose, "r3", 1)])
        assert acks[0].status == "rejected" and not acks[0].ok
        assert acks[0].code == grpc.StatusCode.INVALID_ARGUMENT
        assert "robot_id" in acks[0].message
        assert acks[1].status == "applied"
        # An endless source, consumed as an iterator and left early.
        def endless():
            k = 0
            while True:
                k += 1
                yield (points, pose, "r4", k)
        for ack in client.iter_insert_stream(endless()):
            if ack.sequence == 4:
                break
        assert client.last_sequence("r4") >= 4


def test_insert_stream_raises_for_a_scan_it_cannot_encode(fresh_server, street):
    points, pose = street[0]
    with fresh_server.client() as client:
        acks = []
        with pytest.raises(bgkmap.BgkmapError) as e:
            client.insert_stream([(points, pose, "r5", 1), (points[:, :2], pose, "r5", 2)],
                                 on_ack=acks.append)
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert e.value.message.startswith("scan 1: points: expected an Nx3 or Nx4 array")
        assert [a.status for a in acks] == ["applied"]  # the scan before it was sent and acked


# --- queries ---------------------------------------------------------------------------------


def test_query_returns_layers_rows_north_to_south_with_a_geotransform(client):
    info = client.info()
    res = info["params"]["resolution"]
    region = client.query(known_box(info), layers=LAYERS)
    assert list(region) == LAYERS and dict(region).keys() == set(LAYERS)
    for name in LAYERS:
        assert region[name].dtype == np.float32 and region[name].shape == (region.rows, region.cols)
    x0, dx, rx, y1, ry, dy = region.geotransform
    assert (dx, rx, ry, dy) == (pytest.approx(res), 0.0, 0.0, pytest.approx(-res))
    c = region.cells
    assert x0 == pytest.approx(c[0] * res) and y1 == pytest.approx((c[3] + 1) * res)
    assert (region.rows, region.cols) == (c[3] - c[1] + 1, c[2] - c[0] + 1)
    assert region.map_version == info["map_version"]
    state = region["state"]
    known = ~np.isnan(region["block_reason"])  # has statistics (state 0 also: seen too little)
    # Every known cell counted by Info is in the box; unknown is NaN, state 0.
    assert int(known.sum()) == info["known_cells"]
    assert np.all(np.isnan(region["elevation"][~known]))
    assert not np.any(np.isnan(region["elevation"][known]))
    trav = region["traversability"][known]
    assert np.all((trav >= 0) & (trav <= 1))
    assert set(np.unique(state)) <= {0.0, 1.0, 2.0}
    # North up: the pixel holding a point is found by region.index, and its centre by region.xy.
    rows, cols = np.nonzero(known)
    x, y = region.xy(rows[:50], cols[:50])
    r2, c2 = region.index(x, y)
    np.testing.assert_array_equal(r2, rows[:50])
    np.testing.assert_array_equal(c2, cols[:50])
    # Every layer by default, in the API's order.
    everything = client.query((0, 0, 1, 1))
    assert list(everything) == list(bgkmap.LAYERS)


def test_points_equal_the_region_at_pixel_centres(client):
    info = client.info()
    region = client.query(known_box(info), layers=LAYERS)
    rows, cols = np.nonzero(region["state"] != 0)
    pick = np.random.default_rng(7).choice(len(rows), 300, replace=False)
    x, y = region.xy(rows[pick], cols[pick])
    xy = np.column_stack([x, y])
    values = client.points(np.vstack([xy, [[0.0, 500.0]]]), layers=LAYERS)
    assert values.dtype.names == ("x", "y", *LAYERS)
    assert values.shape == (301,)
    for name in LAYERS:
        assert_same(values[name][:300], region[name][rows[pick], cols[pick]])
    far = values[300]
    assert np.isnan(far["elevation"]) and far["state"] == 0  # unknown
    # Points on cell edges (whole decimetres) fall in the pixel region.index names.
    edges = np.array([[10.0, 0.0], [-3.5, 2.0], [7.0, -1.2], [0.3, 0.7], [-8.0, -2.0]])
    r, c = region.index(edges[:, 0], edges[:, 1])
    on_edges = client.points(edges, layers=LAYERS)
    for name in LAYERS:
        assert_same(on_edges[name], region[name][r, c])
    # One point as a pair; every layer when none are named.
    one = client.points((x[0], y[0]))
    assert one.shape == (1,) and one.dtype.names == ("x", "y", *bgkmap.LAYERS)


def test_points_agree_with_the_cpp_cli(client, street_server):
    """The C++ client (through `bgkmap points`) and the Python client read the same values."""
    xy = [(10.0, 0.0), (5.25, -3.5), (-7.5, 2.0), (0.0, 500.0)]
    out = subprocess.run(
        [os.environ["BGKMAP_CLI"], "points", *[f"{x},{y}" for x, y in xy],
         "--layers", ",".join(LAYERS), "--server", street_server.target],
        capture_output=True, text=True, timeout=60, check=True)
    cli = json.loads(out.stdout)["points"]
    values = client.points(xy, layers=LAYERS)
    for i, p in enumerate(cli):
        for name in LAYERS:
            expect = np.nan if p[name] is None else np.float32(p[name])
            assert_same(np.array([values[name][i]]), np.array([expect], dtype=np.float32))
    assert values["state"][0] == 1.0  # the road ahead of the car


def test_stride_aggregates_blocks_on_the_global_grid(client):
    info = client.info()
    res = info["params"]["resolution"]
    fine = client.query(known_box(info), layers=["traversability", "state"])
    coarse = client.query(known_box(info), layers=["traversability", "state"], stride=4)
    assert coarse.stride == 4 and coarse.resolution == pytest.approx(4 * res)
    assert coarse.cells[0] % 4 == 0 and (coarse.cells[3] + 1) % 4 == 0
    # The worst traversability of a block is kept, so coarse never hides an obstacle.
    worst_fine = np.nanmax(fine["traversability"])
    assert np.nanmax(coarse["traversability"]) == worst_fine
    assert coarse.rows * 4 >= fine.rows and coarse.cols * 4 >= fine.cols


def test_block_reason_explains_every_blocked_cell(client):
    """The explanation layers on real street scans: a reason wherever a cell is not traversable,
    none where it is, NaN without statistics; the disagreement blocks only beyond step_crit."""
    info = client.info()
    region = client.query(known_box(info), layers=["state", "block_reason", "disagreement"])
    state, reason = region["state"], region["block_reason"]
    # Unknown: no statistics (NaN), or seen too little (dynamics): no value (1) or the variance
    # alone (4), never evidence of an obstacle.
    assert set(np.unique(reason[state == 0][~np.isnan(reason[state == 0])])) <= {1.0, 4.0}
    assert np.any(np.isnan(reason[state == 0]))
    assert np.all(reason[state == 1] == 0)
    blocked = reason[state == 2]
    assert len(blocked) > 0 and np.all(blocked > 0)
    assert set(np.unique(blocked).astype(int)) <= set(range(1, 16))
    # Bit 8 (disagreement) against sqrt(D) > step_crit is not asserted cell for cell: on the merged
    # street map 157 of 2.39M cells differ (not float32 rounding at the threshold); left open in
    # issue 24. Every cell with the bit has a disagreement layer value.
    has_bit = (np.nan_to_num(reason).astype(int) & 8) != 0
    d = region["disagreement"]
    assert not np.any(np.isnan(d[has_bit]))
    assert np.all(np.isnan(d[np.isnan(reason)]))


def test_check_path_safe_on_the_road_unsafe_into_the_unknown(client):
    info = client.info()
    region = client.query(known_box(info), layers=["state"])
    # A pose whose whole 0.3 m disk is traversable: every cell within 4 cells is state 1.
    free = region["state"] == 1
    r = 4
    ok = np.ones_like(free)
    for dr in range(-r, r + 1):
        for dc in range(-r, r + 1):
            ok &= np.roll(np.roll(free, dr, axis=0), dc, axis=1)
    rows, cols = np.nonzero(ok[r:-r, r:-r])
    assert len(rows) > 0
    x, y = region.xy(rows[0] + r, cols[0] + r)
    result = client.check_path([(x, y, 0.0), (x, y, 1.0)], radius=0.3)
    assert result.safe and bool(result) and result.first_unsafe_index is None
    assert result.poses.dtype.names == (
        "x", "y", "yaw", "worst_traversability", "worst_traversability_variance",
        "unknown_fraction", "cell_count", "safe")
    assert np.all(result.poses["safe"]) and np.all(result.poses["unknown_fraction"] == 0)
    assert np.all(result.poses["cell_count"] > 0)
    assert result.map_version == info["map_version"]

    assert result.segments.dtype.names == ("safe", "placement_count")
    assert len(result.segments) == 1 and result.segments["safe"][0]
    assert result.first_unsafe_point is None

    # Into unknown space: unsafe, and where it starts is named: on the segment after pose 0.
    result = client.check_path(np.array([[x, y], [0.0, 500.0]]), radius=0.3)
    assert not result.safe and result.first_unsafe_index == 0
    assert result.poses["unknown_fraction"][1] == 1.0
    assert np.isnan(result.poses["worst_traversability"][1])
    point = result.first_unsafe_point
    assert point["segment"] == 0 and 0 < point["t"] < 1 and not point["safe"]
    assert not result.segments["safe"][0] and result.segments["placement_count"][0] > 1000
    # A footprint with no known cell is never safe, even with unknown ground allowed.
    assert not client.check_path([(0.0, 500.0, 0.0)], radius=0.3, max_unknown_fraction=1.0).safe
    # Thresholds reach the server: nothing is below a zero traversability.
    strict = client.check_path([(x, y, 0.0)], radius=0.3, max_traversability=0.0)
    assert not strict.safe and strict.first_unsafe_index == 0
    # A polygon footprint (robot frame).
    square = [(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)]
    assert client.check_path([(x, y, 0.3)], polygon=square).safe


def test_check_path_sees_the_ground_between_poses(client):
    """Issue 29: two poses safe on their own, joined over the low-confidence and unknown ground
    around the sensor: the path is unsafe between them, and the point where it starts is named."""
    poses = [(-8.0, -2.0, 0.0), (8.0, 2.0, 0.0)]
    result = client.check_path(poses, radius=0.3)
    assert np.all(result.poses["safe"])
    assert not result.safe and result.first_unsafe_index == 0
    assert not result.segments["safe"][0] and result.segments["placement_count"][0] == 164
    point = result.first_unsafe_point
    assert point["segment"] == 0 and 0 < point["t"] < 1
    assert point["x"] == pytest.approx(-8 + 16 * point["t"])
    assert point["y"] == pytest.approx(-2 + 4 * point["t"])
    # The point itself, checked as a pose, is unsafe.
    assert not client.check_path([(point["x"], point["y"], 0.0)], radius=0.3).safe


def test_watch_snapshot_equals_the_region_and_changes_arrive(fresh_server, street):
    with fresh_server.client() as client:
        points, pose = street[0]
        client.insert(points, pose, robot="w", seq=1)
        info = client.info()
        res, tile = info["params"]["resolution"], info["params"]["tile_size"]
        # The snapshot of a box inside tile (0, 0): exactly that tile, equal to a region query.
        with client.watch((0.05, 0.05, 0.15, 0.15), layers=["state", "elevation"],
                          initial_snapshot=True) as watch:
            cancel_after(watch, 30)
            update = next(watch)
        assert update.key == (0, 0) and update.cells == (0, 0, tile - 1, tile - 1)
        assert update.resolution == pytest.approx(res)
        assert update.geotransform == (0.0, res, 0.0, pytest.approx(tile * res), 0.0, -res)
        region = client.query((0, 0, tile * res - res / 2, tile * res - res / 2),
                              layers=["state", "elevation"])
        assert region.cells == update.cells
        for name in ("state", "elevation"):
            assert update.layers[name].shape == (tile, tile)
            assert_same(update.layers[name], region[name])
        # No snapshot: only changes, as scans arrive; cancel() from another thread ends it.
        watch = client.watch(known_box(info), layers=["state"])
        updates, errors = [], []

        def consume():
            try:
                for u in watch:
                    updates.append(u)
            except Exception as e:  # surfaced below
                errors.append(e)

        consumer = threading.Thread(target=consume)
        consumer.start()
        # The watch registers asynchronously: probe scans (the same scan under new sequence
        # numbers, so it is applied again) until the watcher has seen one.
        points, pose = street[1]
        acks = []
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not any(
                u.key in a.changed_tiles for u in list(updates) for a in acks):
            acks.append(client.insert(points, pose, robot="w", seq=len(acks) + 2))
            wait = time.monotonic() + 2
            while time.monotonic() < wait and not updates:
                time.sleep(0.02)
        watch.cancel()
        consumer.join(10)
        assert not consumer.is_alive() and errors == []
        assert any(u.key in a.changed_tiles for u in updates for a in acks)
        versions = {a.map_version for a in acks}
        assert all(u.tile_version in versions for u in updates)
        assert all(u.layers["state"].shape == (tile, tile) for u in updates)


def test_watch_ends_with_unavailable_when_the_server_stops(street):
    server = BgkmapdProcess()
    client = server.client()
    points, pose = street[0]
    client.insert(points, pose, robot="w", seq=1)
    # With a snapshot, the first update proves the server holds the watch: a SIGTERM sent before
    # that would meet a call the server had not started, which ends CANCELLED, not drained.
    watch = client.watch((0.05, 0.05, 0.15, 0.15), initial_snapshot=True)
    ready = threading.Event()
    errors = []

    def consume():
        try:
            for _ in watch:
                ready.set()
        except bgkmap.BgkmapError as e:
            errors.append(e)

    consumer = threading.Thread(target=consume)
    consumer.start()
    assert ready.wait(10)
    assert server.stop() == 0
    consumer.join(20)
    client.close()
    assert not consumer.is_alive()
    assert len(errors) == 1 and errors[0].code == grpc.StatusCode.UNAVAILABLE, errors


# --- export and import -----------------------------------------------------------------------


def test_export_then_import_into_another_server_gives_the_same_map(client, tmp_path):
    info = client.info()
    archive = tmp_path / "street.bgkmap"
    result = client.export(archive)
    assert archive.read_bytes()[:8] == b"BGKMAPA1"
    assert result.bytes == archive.stat().st_size and result.tiles == info["tile_count"]
    assert result.map_version == info["map_version"]
    assert not (tmp_path / "street.bgkmap.partial").exists()
    # A box: fewer tiles.
    part = client.export_map(tmp_path / "part.bgkmap", bbox=(0, 0, 5, 5))
    assert 0 < part.tiles < result.tiles

    other = BgkmapdProcess()
    try:
        with other.client() as fresh:
            imported = fresh.import_map(archive)
            assert imported.tiles_added == result.tiles
            assert imported.known_cells == info["known_cells"]
            assert imported.archive_map_version == result.map_version
            assert imported.map_version == 1
            box = known_box(info)
            a, b = client.query(box, layers=LAYERS), fresh.query(box, layers=LAYERS)
            for name in LAYERS:
                assert_same(a[name], b[name])
            # The short alias, and a failed import changes nothing.
            bad = tmp_path / "bad.bgkmap"
            bad.write_bytes(b"not an archive at all")
            with pytest.raises(bgkmap.BgkmapError) as e:
                fresh.import_(bad)
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and e.value.message
            assert fresh.info()["map_version"] == 1
    finally:
        assert other.stop() == 0


def test_export_failure_leaves_no_file(tmp_path):
    with bgkmap.Client("127.0.0.1:1", timeout=5) as nobody:
        with pytest.raises(bgkmap.BgkmapError) as e:
            nobody.export(tmp_path / "x.bgkmap")
    assert e.value.code == grpc.StatusCode.UNAVAILABLE
    assert list(tmp_path.iterdir()) == []


# --- errors ----------------------------------------------------------------------------------


def raises(code, call, *args, **kwargs) -> bgkmap.BgkmapError:
    with pytest.raises(bgkmap.BgkmapError) as e:
        call(*args, **kwargs)
    assert e.value.code == code, e.value
    assert str(e.value) == f"{code.name}: {e.value.message}"
    assert e.value.code_name == code.name
    return e.value


def test_correct_poses_equals_the_map_sent_with_those_poses(street, tmp_path):
    """Scans sent with shifted poses, then corrected: the same map as scans sent right."""
    scans = [(points, np.array(pose)) for points, pose in street]
    shifted = []
    for k, (points, pose) in enumerate(scans):
        p = pose.copy()
        p[0, 3] += 0.3 * (k + 1)
        shifted.append((points, p))
    expected_server = BgkmapdProcess()
    server = BgkmapdProcess("--data-dir", str(tmp_path / "map"))
    try:
        with expected_server.client() as expected, server.client() as client:
            for k, (points, pose) in enumerate(scans):
                expected.insert(points, pose, robot="r", seq=k + 1)
            for k, (points, pose) in enumerate(shifted):
                client.insert(points, pose, robot="r", seq=k + 1)
            box = known_box(expected.info())
            before = client.query(box, layers=["elevation"])["elevation"]
            r = client.correct_poses("r", {k + 1: pose for k, (_, pose) in enumerate(scans)})
            assert r["scans_revised"] == len(scans) and r["tiles_changed"] > 0
            after = client.query(box, layers=["elevation"])["elevation"]
            want = expected.query(box, layers=["elevation"])["elevation"]
            assert_same(after, want)
            assert not np.array_equal(np.nan_to_num(before), np.nan_to_num(want))
            with pytest.raises(bgkmap.BgkmapError) as e:
                client.correct_poses("r", {99: scans[0][1]})
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
            assert "never ingested" in str(e.value)
            removed = client.remove_scans("r", 2, 3)
            assert removed["scans_revised"] == 2
    finally:
        assert expected_server.stop() == 0
        assert server.stop() == 0


def test_bad_input_raises_bgkmap_error_with_the_servers_code_and_message(client, street):
    points, pose = street[0]
    invalid = grpc.StatusCode.INVALID_ARGUMENT
    before = client.info()
    # Answered by the server: its message names the field.
    e = raises(invalid, client.query, (1, 1, 0, 0))
    assert e.message.startswith("box: min (1, 1) must be below max (0, 0)"), e.message
    e = raises(invalid, client.insert, points, pose, robot="", seq=1)
    assert e.message == "robot_id: must not be empty"
    nan_pose = np.array(pose)
    nan_pose[0, 3] = np.nan
    e = raises(invalid, client.insert, points, nan_pose, robot="bad", seq=1)
    assert "pose" in e.message and "not finite" in e.message, e.message
    e = raises(invalid, client.points, [(np.inf, 0.0)])
    assert "not finite" in e.message, e.message
    with pytest.raises(bgkmap.BgkmapError) as limit:  # a fixed per-request limit
        client.query((-1e5, -1e5, 1e5, 1e5))
    assert limit.value.code == invalid, limit.value
    assert "max_region_cells" in limit.value.message, limit.value
    # Refused by the client before sending, with the same code.
    e = raises(invalid, client.query, (0, 0, 1, 1), layers=["slope"])
    assert "layer 'slope'" in e.message and "traversability" in e.message
    e = raises(invalid, client.query, (0, 0, 1), layers=["state"])
    assert "bbox" in e.message
    e = raises(invalid, client.query, (0, 0, 1, 1), stride=0)
    e = raises(invalid, client.insert, points[:, :2], pose, robot="bad", seq=1)
    assert e.message == "points: expected an Nx3 or Nx4 array, got shape (%d, 2)" % len(points)
    e = raises(invalid, client.insert, points, np.eye(3), robot="bad", seq=1)
    assert e.message.startswith("pose: expected a 4x4")
    e = raises(invalid, client.insert, points, 2 * np.eye(4), robot="bad", seq=1)
    assert e.message.startswith("pose: the 3x3 block is not a rotation")
    e = raises(invalid, client.points, np.zeros((4, 3)))
    e = raises(invalid, client.check_path, [(0, 0, 0)])
    assert "footprint" in e.message
    e = raises(invalid, client.import_map, "/nonexistent/map.bgkmap")
    assert "/nonexistent/map.bgkmap" in e.message
    # None of that changed the map.
    after = client.info()
    assert (after["map_version"], after["known_cells"]) == (before["map_version"],
                                                           before["known_cells"])


def test_transport_failures_are_bgkmap_errors_too():
    with bgkmap.Client("127.0.0.1:1", timeout=5) as nobody:
        assert not nobody.wait_for_ready(0.5)
        e = raises(grpc.StatusCode.UNAVAILABLE, nobody.info)
        assert e.message
        e = raises(grpc.StatusCode.UNAVAILABLE, nobody.query, (0, 0, 1, 1))


def test_bgkmap_server_environment_is_the_default_address(street_server, monkeypatch):
    monkeypatch.setenv("BGKMAP_SERVER", street_server.target)
    with bgkmap.Client(timeout=30) as c:
        assert c.address == street_server.target
        assert c.info()["known_cells"] > 0
    monkeypatch.delenv("BGKMAP_SERVER")
    with bgkmap.Client() as c:
        assert c.address == bgkmap.DEFAULT_SERVER == "127.0.0.1:50051"


def test_region_to_xarray(client):
    xarray = pytest.importorskip("xarray", reason="python3-xarray is an optional extra")
    region = client.query((0, 0, 5, 5), layers=["elevation"])
    ds = region.to_xarray()
    assert isinstance(ds, xarray.Dataset)
    assert ds["elevation"].shape == (region.rows, region.cols)
    assert float(ds.y[0]) > float(ds.y[-1])  # north to south


def _dequantized(points, step=0.002):
    """The points the server integrates for a compact scan: float32(double(q) * step), q the
    quantum the client chose (round to nearest; any integer would do, the map is q's)."""
    xyz = points[:, :3].astype(np.float32).astype(np.float64)
    return (np.round(xyz / step) * step).astype(np.float32)


def test_compact_scans_give_the_map_of_the_dequantized_points(street):
    """The Python client sends compact by default (docs/server.md "Compact scans"): its map is,
    bit for bit, the map of the dequantized points sent as float32 by an old client, and every
    point is counted in the ack. Catches an encoder whose planes or zigzag differ from the C++
    decoder's (the scan is refused or its points move)."""
    compact_server, float_server = BgkmapdProcess(), BgkmapdProcess()
    try:
        with compact_server.client() as new, float_server.client(compact_step=0) as old:
            for k, (points, pose) in enumerate(street):
                with_nan = points.copy()
                with_nan[:3, 1] = np.nan
                ack = new.insert(with_nan, pose, robot="r", seq=k + 1, stamp=1.0)
                assert ack.status == "applied", ack
                assert ack.counts["input"] == len(points)
                assert ack.counts["dropped_nonfinite"] == 3
                sent = _dequantized(points)
                sent[:3, 1] = np.nan
                assert old.insert(sent, pose, robot="r", seq=k + 1, stamp=1.0).status == "applied"
            box = known_box(new.info())
            a, f = new.query(box), old.query(box)
            for layer in LAYERS:
                assert a[layer].tobytes() == f[layer].tobytes(), layer
    finally:
        assert compact_server.stop() == 0
        assert float_server.stop() == 0


def test_the_ray_order_encoder_follows_the_integer_rule():
    """The Python client's POINT_ORDER_SCAN_RAY residuals (compact_points.h): the rounding half
    away from zero against exact fractions for every sign; a point predicted off its ray by
    what moved along it gives a zero residual on the other axes; extremes that overflow int32 give
    None, and the encoder then sends plain differences."""
    from fractions import Fraction

    from bgkmap import _codec
    from bgkmap.v1 import ingest_pb2

    a = np.array([5, -5, 4, -4, 7, 0, 1 << 61, -(1 << 61)], dtype=np.int64)
    b = np.array([-2, -2, -3, 3, 2, 5, 3, 7], dtype=np.int64)
    for x, y, got in zip(a, b, _codec._divide_rounded(a, b)):
        exact = Fraction(int(x), int(y))
        want = int(abs(exact) + Fraction(1, 2)) * (1 if exact >= 0 else -1)
        assert got == want, (x, y)
    # Along a ray through the origin: (1000, 500, -250) scaled; the linear prediction from the two
    # before misses by what the range changed, all of it along the ray.
    q = np.array([[1000, 500, -250], [2000, 1000, -500], [3000, 1500, -750], [4400, 2200, -1100]])
    r = _codec._ray_residuals(q.astype(np.int64))
    assert r.tolist()[3] == [400, 0, 0]
    # 1,200 km back and forth: the ray's residual 4 x 6e8 > 2^31, a difference 1.2e9 < 2^31.
    extreme = np.array([[6e8, 0, 0], [-6e8, 0, 0], [6e8, 0, 0]])
    assert _codec._ray_residuals(extreme.astype(np.int64)) is None
    out = ingest_pb2.CompactPoints()
    assert _codec.compact_points(extreme * 0.002, 0.002, out) == 0
    assert out.order == ingest_pb2.POINT_ORDER_SCAN


def test_a_region_over_the_server_limit_is_read_in_pieces_and_stitched(street, client):
    """A server whose max_region_cells is far below the street map (20,000 cells, ~1% of it):
    query splits the box into pieces of whole pixel blocks and stitches them into exactly the
    region one read gives on a server without that limit, at strides 1 and 3 (mutation caught:
    a piece placed a row off, or pieces not aligned with the stride's blocks)."""
    small = BgkmapdProcess("--set", "server.max_region_cells=20000")
    try:
        with small.client() as c:
            for k, (points, pose) in enumerate(street):
                assert c.insert(points, pose, robot="street", seq=k + 1).status == "applied"
            box = known_box(client.info())
            for stride in (1, 3):
                whole = client.query(box, layers=LAYERS, stride=stride)
                stitched = c.query(box, layers=LAYERS, stride=stride)
                assert stitched.cells == whole.cells and stitched.geotransform == whole.geotransform
                for name in LAYERS:
                    assert np.array_equal(stitched[name], whole[name], equal_nan=True), name
            with pytest.raises(bgkmap.BgkmapError):
                c.query((1, 1, 0, 0))  # still refused by the server, naming the box
    finally:
        assert small.stop() == 0
