"""Region deltas and MapMirror (issue 27) against real bgkmapd processes on the street scans: a
delta holds the changed tiles of a full query bit for bit, a clear sends tombstones, a mirror kept
by watch + deltas equals a fresh full query after scans, a clear, an import and a pose correction,
and a version the server cannot answer exactly comes back whole, flagged."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import bgkmap
from conftest import BgkmapdProcess

BOX = (-30.0, -25.0, 35.0, 30.0)


def sub_scans(street, parts: int):
    """Each street scan split into `parts` interleaved scans: (points, pose) in sending order."""
    out = []
    for points, pose in street:
        for j in range(parts):
            out.append((np.asarray(points)[j::parts], np.array(pose)))
    return out


def send(client, scans, first_seq: int, robot: str = "m") -> set:
    """Inserts scans as robot's first_seq.. and returns the tiles they changed."""
    changed = set()
    for k, (points, pose) in enumerate(scans):
        ack = client.insert(points, pose, robot=robot, seq=first_seq + k)
        assert ack.status == "applied", ack
        changed.update(tuple(t) for t in ack.changed_tiles)
    return changed


def same_bits(a: bgkmap.Region, b: bgkmap.Region) -> bool:
    return list(a) == list(b) and all(
        np.array_equal(a[n].view(np.uint32), b[n].view(np.uint32)) for n in a)


def test_a_delta_after_one_scan_holds_the_changed_tiles_bit_for_bit(fresh_server, street):
    scans = sub_scans(street, 3)
    with fresh_server.client() as client:
        send(client, scans[:5], 1)
        before = client.query(BOX)
        assert before.history_id != 0
        changed = send(client, scans[5:6], 6)
        delta = client.query(BOX, since=before.map_version, history_id=before.history_id)
        assert not delta.full and delta.region is None, delta.resync_reason
        # Only tiles the scan changed that meet the region (6.4 m tiles); at stride 1, their
        # changed blocks (several patches may name one tile).
        lo = [int(np.floor(v / 6.4)) for v in BOX[:2]]
        hi = [int(np.floor((v - 1e-9) / 6.4)) for v in BOX[2:]]
        inside = {k for k in changed if lo[0] <= k[0] <= hi[0] and lo[1] <= k[1] <= hi[1]}
        assert {p.key for p in delta.patches} <= inside and delta.patches
        full = client.query(BOX)
        for p in delta.patches:
            window = (slice(p.row, p.row + p.rows), slice(p.col, p.col + p.cols))
            if p.tombstone:  # a block written and left unknown: unknown in the full answer
                assert np.isnan(full["elevation"][window]).all() and (full["state"][window] == 0).all()
                continue
            for name, values in p.layers.items():
                want = full[name][window]
                assert np.array_equal(values.view(np.uint32), want.view(np.uint32)), (p.key, name)
        assert not all(p.tombstone for p in delta.patches)
        assert same_bits(delta.apply_to(before), full)
        # Nothing changed since: nothing sent.
        again = client.query(BOX, since=delta.map_version, history_id=delta.history_id)
        assert not again.full and again.patches == []


def test_a_clear_sends_tombstones(fresh_server, street):
    with fresh_server.client() as client:
        send(client, sub_scans(street, 2), 1)
        mirror = bgkmap.MapMirror(client, BOX, layers=["elevation", "state", "block_reason"],
                                  compress=True)  # gzip on the wire: the same values
        client.clear((-6.4, -6.4, 6.4, 6.4))  # tiles (-1..0, -1..0) whole
        delta = mirror.refresh()
        assert not delta.full
        assert {p.key for p in delta.patches if p.tombstone} == {(-1, -1), (-1, 0), (0, -1), (0, 0)}
        assert all(p.layers == {} for p in delta.patches if p.tombstone)
        assert same_bits(mirror.region, client.query(BOX, layers=mirror.layers))


def test_a_mirror_equals_a_fresh_query_after_scans_a_clear_an_import_and_a_correction(
        street, tmp_path):
    scans = sub_scans(street, 3)
    drifted = [(points, pose.copy()) for points, pose in scans]
    for k, (_, pose) in enumerate(drifted):
        pose[0, 3] += 0.05 * (k + 1)
    server = BgkmapdProcess("--data-dir", str(tmp_path / "map"))
    try:
        with server.client() as client:
            send(client, drifted[:3], 1)
            mirror = bgkmap.MapMirror(client, BOX, stride=2)

            def check(what: str, full_expected: bool = False):
                delta = mirror.refresh()
                assert delta.full == full_expected, (what, delta.resync_reason)
                fresh = client.query(BOX, stride=2)
                assert mirror.version == fresh.map_version, what
                assert same_bits(mirror.region, fresh), what
                return delta

            send(client, drifted[3:6], 4)
            assert check("scans").patches
            r = client.correct_poses("m", {k + 1: pose for k, (_, pose) in enumerate(scans[:6])})
            assert r["tiles_changed"] > 0
            assert check("correction").patches
            client.clear((-3, -3, 9, 4))
            check("clear")
            archive = tmp_path / "part.bgkmap"
            client.export_map(archive, bbox=(0, 0, 20, 20))
            client.import_map(archive)
            assert check("import").patches
            send(client, drifted[6:], 7)
            check("more scans")
            assert mirror.resyncs == 0 and mirror.refreshes == 5
    finally:
        assert server.stop() == 0


def test_follow_keeps_the_mirror_current_from_watch_events(fresh_server, street):
    scans = sub_scans(street, 3)
    with fresh_server.client() as client:
        send(client, scans[:2], 1)
        mirror = bgkmap.MapMirror(client, BOX, layers=["elevation", "state"])
        target = mirror.version + len(scans) - 2
        errors = []

        def follow():
            try:
                for _ in mirror.follow(stop_version=target):
                    pass
            except Exception as e:  # surfaced below
                errors.append(e)

        follower = threading.Thread(target=follow)
        follower.start()
        send(client, scans[2:], 3)
        follower.join(60)
        assert not follower.is_alive() and not errors, errors
        assert mirror.version == target
        assert same_bits(mirror.region, client.query(BOX, layers=mirror.layers))


def test_a_version_the_server_cannot_answer_exactly_comes_back_whole(street, tmp_path):
    scans = sub_scans(street, 2)
    server = BgkmapdProcess("--data-dir", str(tmp_path / "map"))
    try:
        with server.client() as client:
            send(client, scans[:2], 1)
            region = client.query(BOX)
            ahead = client.query(BOX, since=region.map_version + 5)
            assert ahead.full and "ahead" in ahead.resync_reason
            assert same_bits(ahead.region, region)
            other = client.query(BOX, since=region.map_version, history_id=region.history_id + 1)
            assert other.full and "history_id" in other.resync_reason
    finally:
        assert server.stop() == 0
    restarted = BgkmapdProcess("--data-dir", str(tmp_path / "map"))
    try:
        with restarted.client() as client:
            mirror_region = region
            delta = client.query(BOX, since=region.map_version, history_id=region.history_id)
            assert delta.full  # another run of the server: a new history
            assert same_bits(delta.apply_to(mirror_region), client.query(BOX))
            with pytest.raises(bgkmap.BgkmapError):
                client.query(BOX, since=-1)
    finally:
        assert restarted.stop() == 0
