"""bgkmap.MapMirror: a local numpy copy of a region, kept current by region deltas.

    mirror = bgkmap.MapMirror(client, (-50, -50, 50, 50), layers=["elevation", "state"])
    for delta in mirror.follow():       # blocks: one delta per change the watch reports
        plan_on(mirror.region)          # a bgkmap.Region, equal to a fresh client.query(...)

The watch only says *that* tiles changed (it is asked for the state layer, the smallest); the
data comes by deltas: QueryRegion with since_version answers the tiles changed since the
mirror's version, with tombstones for tiles a clear emptied (docs/server.md, "Region deltas").
When the server cannot answer a delta exactly (it restarted, or the mirror is older than what it
recorded) it answers the whole region, and the mirror replaces its copy, so after every refresh
the copy equals a full query at its map_version bit for bit.
"""

from __future__ import annotations

from typing import Iterator, Optional

from bgkmap.results import Region, RegionDelta


class MapMirror:
    """A region of the served map kept current. region: the copy (a Region, updated in place by
    deltas); version / history_id: what the next delta asks from. bytes_received counts the
    serialized answers (the first full one included), refreshes and resyncs the refreshes and
    how many of them came back whole."""

    def __init__(self, client, bbox, layers=None, stride: int = 1, compress: bool = False):
        self.client = client
        self.bbox = tuple(bbox)
        self.layers = layers
        self.stride = int(stride)
        self.compress = bool(compress)  # gzip on the wire (bytes_received counts before it)
        self.region: Region = client.query(self.bbox, layers, self.stride, compress=self.compress)
        self.bytes_received = self.region.wire_bytes
        self.refreshes = 0
        self.resyncs = 0

    @property
    def version(self) -> int:
        return self.region.map_version

    @property
    def history_id(self) -> int:
        return self.region.history_id

    def refresh(self) -> RegionDelta:
        """Asks what changed since the copy's version and applies it; returns the answer."""
        delta = self.client.query(self.bbox, self.layers, self.stride, since=self.version,
                                  history_id=self.history_id, compress=self.compress)
        self.region = delta.apply_to(self.region)
        self.bytes_received += delta.wire_bytes
        self.refreshes += 1
        self.resyncs += int(delta.full)
        return delta

    def follow(self, *, stop_version: Optional[int] = None) -> Iterator[RegionDelta]:
        """Refreshes whenever the watch reports a change the copy does not hold yet, yielding each
        answer; the first refresh covers what changed before the watch began. Runs until the
        caller stops iterating, or once the copy's version reaches stop_version. Watch errors
        raise BgkmapError (UNAVAILABLE when the server stops)."""
        with self.client.watch(self.bbox, layers=["state"]) as watch:
            yield self.refresh()
            if stop_version is not None and self.version >= stop_version:
                return
            for update in watch:
                # A tile read at a map version the copy already holds brings nothing new.
                if update.map_version <= self.version:
                    continue
                yield self.refresh()
                if stop_version is not None and self.version >= stop_version:
                    return
