"""bgkmap: the Python client of the bgkmapd terrain map server (API bgkmap.v1).

    import bgkmap
    with bgkmap.Client("127.0.0.1:50051") as client:
        client.insert(points, pose, robot="r1", seq=1)
        region = client.query((-20, -20, 20, 20), layers=["traversability", "state"])

docs/python.md describes every call. The generated protocol modules are bgkmap.v1.*_pb2.
"""

from bgkmap._version import __version__
from bgkmap._codec import LAYERS
from bgkmap.client import DEFAULT_SERVER, Client, Watch
from bgkmap.errors import BgkmapError
from bgkmap.kitti import KittiSequence
from bgkmap.mirror import MapMirror
from bgkmap.results import (ExportResult, ImportResult, PathCheck, Region, RegionDelta,
                            RegionPatch, Scan, ScanAck, TileUpdate)

__all__ = [
    "BgkmapError", "Client", "DEFAULT_SERVER", "ExportResult", "ImportResult", "KittiSequence",
    "LAYERS", "MapMirror", "PathCheck", "Region", "RegionDelta", "RegionPatch", "Scan", "ScanAck",
    "TileUpdate", "Watch", "__version__",
]
