#!/usr/bin/env python3
"""Bytes of a region refresh (issue 27, docs/benchmarks.md "Region deltas"): for each real
sequence of ../shared/data, a fresh bgkmapd gets the first scans, a planner reads the region
whole, then asks a delta after 1 new scan and after 10 more (QueryRegion with since_version).
Bytes are the serialized RegionChunk messages the client received (gRPC's message bytes, before
its 5-byte prefix and HTTP/2 framing), and, for the same answers asked again with
RegionRequest.compress (gzip), the bytes a counting TCP proxy saw from server to client (HTTP/2
framing included: what a radio carries).

    PYTHONPATH=build/python /usr/bin/python3 scripts/bench-region-delta.py \
        --bgkmapd build/server/bgkmapd --data ../shared/data [--bgkmap build/tools/bgkmap/bgkmap]

With --bgkmap it also simulates the City street the issue measured (a car with a VLP-16 driving
100 m, experiments/robots/car_sim.yaml) and refreshes the street's 50 x 100 m mid-drive.
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import subprocess
import sys
import tempfile
import threading

import numpy as np

import bgkmap

LISTENING = re.compile(r"event=listening .*port=(\d+)")


class Server:
    """bgkmapd on a free loopback port, in memory."""

    def __init__(self, binary: str, *args: str):
        self.process = subprocess.Popen([binary, "--listen", "127.0.0.1:0", *args],
                                        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.PIPE, text=True)
        self.port = 0
        ready = threading.Event()

        def read():
            for line in self.process.stderr:
                m = LISTENING.search(line)
                if m and not self.port:
                    self.port = int(m.group(1))
                    ready.set()
        threading.Thread(target=read, daemon=True).start()
        if not ready.wait(60):
            self.process.kill()
            raise RuntimeError("bgkmapd did not start")

    def stop(self):
        self.process.terminate()
        self.process.wait(60)


def box_around(poses, margin: float, limit_cells: int, resolution: float = 0.1):
    xy = np.array([[p[0][3], p[1][3]] for p in poses])
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    # Within one region query (server.max_region_cells): shrink around the centre if needed.
    side = np.sqrt(limit_cells) * resolution
    centre = (lo + hi) / 2
    half = np.minimum((hi - lo) / 2, side / 2 - resolution)
    return tuple(float(v) for v in (*(centre - half), *(centre + half)))


class CountingProxy:
    """A loopback TCP proxy to `port` counting the bytes sent from the server to the client."""

    def __init__(self, port: int):
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.down = 0
        self.lock = threading.Lock()
        threading.Thread(target=self._accept, args=(port,), daemon=True).start()

    def _accept(self, port: int):
        while True:
            client, _ = self.listener.accept()
            server = socket.create_connection(("127.0.0.1", port))
            threading.Thread(target=self._pump, args=(client, server, False), daemon=True).start()
            threading.Thread(target=self._pump, args=(server, client, True), daemon=True).start()

    def _pump(self, src, dst, count: bool):
        try:
            while data := src.recv(1 << 16):
                if count:
                    with self.lock:
                        self.down += len(data)
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def measure(self, call):
        """call()'s result and the bytes the server sent meanwhile."""
        with self.lock:
            before = self.down
        result = call()
        with self.lock:
            return result, self.down - before


def run(binary: str, name: str, seq: bgkmap.KittiSequence, base: int, margin: float,
        layers, box=None) -> dict:
    server = Server(binary)
    try:
        proxy = CountingProxy(server.port)
        with bgkmap.Client(f"127.0.0.1:{server.port}", timeout=600) as client, \
                bgkmap.Client(f"127.0.0.1:{proxy.port}", timeout=600) as zclient:
            limit = client.info()["limits"]["max_region_cells"]
            if box is None:
                box = box_around([seq[k][1] for k in range(len(seq))], margin, limit)

            def insert(first: int, count: int):
                for k in range(first, min(first + count, len(seq))):
                    points, pose = seq[k]
                    assert client.insert(points, pose, robot="r", seq=k + 1).ok
                return min(first + count, len(seq)) - first

            insert(0, base)
            zclient.info()  # (the limits, asked once, not counted below)
            mirror = bgkmap.MapMirror(client, box, layers=layers)
            full = mirror.region.wire_bytes
            tiles = mirror.region.rows * mirror.region.cols / 64 / 64
            # The same answers gzipped, counted on the wire.
            _, zfull = proxy.measure(lambda: zclient.query(box, layers, compress=True))
            at = (mirror.version, mirror.history_id)
            out = {"sequence": name, "box": box, "base": base, "full": full, "zfull": zfull,
                   "region_tiles": tiles, "pixels": mirror.region.rows * mirror.region.cols}
            for label, count in (("after 1", 1), ("after 10", 10)):
                sent = insert(base, count)
                base += sent
                if sent == 0:
                    continue
                before = {n: a.copy() for n, a in mirror.region.layers.items()}
                _, zdelta = proxy.measure(lambda: zclient.query(
                    box, layers, since=at[0], history_id=at[1], compress=True))
                delta = mirror.refresh()
                at = (mirror.version, mirror.history_id)
                assert not delta.full, delta.resync_reason
                # Pixels whose value changed in any layer: the floor of a cell-level delta.
                differ = np.zeros(before[next(iter(before))].shape, dtype=bool)
                for n, a in before.items():
                    differ |= a.view(np.uint32) != mirror.region[n].view(np.uint32)
                out[label] = (sent, delta.wire_bytes, len(delta.patches),
                              sum(p.tombstone for p in delta.patches),
                              zdelta,
                              int(differ.sum()), sum(p.rows * p.cols for p in delta.patches))
                # The copy is exact: the benchmark would be meaningless otherwise.
                fresh = client.query(box, layers=layers)
                assert all(np.array_equal(mirror.region[n].view(np.uint32),
                                          fresh[n].view(np.uint32)) for n in fresh)
            return out
    finally:
        server.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bgkmapd", required=True)
    ap.add_argument("--data", required=True, help="../shared/data")
    ap.add_argument("--bgkmap", help="the CLI, to simulate the City street as well")
    args = ap.parse_args()
    runs = [
        ("Ouster OS1-128 street", os.path.join(args.data, "ouster_os1_128_street"), 2, 40.0, None,
         None),
        ("KITTI 0048, drive +- 40 m", os.path.join(args.data, "kitti_raw_0048"), 11, 40.0, None,
         None),
        ("KITTI 0048, 200 x 200 m", os.path.join(args.data, "kitti_raw_0048"), 11, 500.0, None,
         None),
        ("KITTI 0048, 200 x 200 m, elevation+state", os.path.join(args.data, "kitti_raw_0048"),
         11, 500.0, ["elevation", "state"], None),
        ("BALM hall, path +- 10 m", os.path.join(args.data, "balm_hall"), 48, 10.0, None, None),
    ]
    scratch = tempfile.TemporaryDirectory(prefix="bgkmap-region-delta-")
    if args.bgkmap:
        city = os.path.join(scratch.name, "city")
        subprocess.run([args.bgkmap, "simulate", "city", "--config",
                        os.path.join(os.path.dirname(__file__), "..", "experiments", "robots",
                                     "car_sim.yaml"),
                        "--length", "100", "--out", city], check=True, stdout=subprocess.DEVNULL)
        runs.append(("simulated City street, VLP-16 (50 x 100 m)", city, 50, 0.0, None,
                     (-25.0, 0.0, 25.0, 100.0)))
    print("| sequence | region (pixels, tiles) | full answer bytes | after 1 scan: bytes (patches, "
          "ratio) | after 10 scans: bytes (patches, ratio) | gzip on the wire: full, after 1, after 10 |")
    print("|---|---|---|---|---|---|")
    for name, folder, base, margin, layers, box in runs:
        seq = bgkmap.KittiSequence(folder)
        r = run(args.bgkmapd, name, seq, base, margin, layers, box)

        def cell(label):
            if label not in r:
                return "n/a (no more scans)"
            sent, b, tiles, tomb, z, differ, patched = r[label]
            return (f"{b:,} ({tiles} patches, 1/{r['full'] / b:.1f}; {differ:,} of {patched:,} "
                    "pixels sent changed)") if b else "0"

        zs = [f"{r['zfull']:,}"] + [f"{r[k][4]:,}" for k in ("after 1", "after 10") if k in r]
        print(f"| {name} | {r['pixels']:,}, {r['region_tiles']:.0f} | {r['full']:,} | "
              f"{cell('after 1')} | {cell('after 10')} | {', '.join(zs)} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
