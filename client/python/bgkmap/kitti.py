"""KITTI-like scan directories, as `bgkmap insert` and `bgkmap build` read them (tools/io):
velodyne/NNNNNN.bin (float32 x, y, z, intensity in the sensor frame, numbered from 0) and
poses.txt (one row-major 3x4 T_map_sensor per scan)."""

from __future__ import annotations

import os
import re
from typing import Iterator, Tuple

import numpy as np

_SCAN_NAME = re.compile(r"^(\d+)\.bin$")


def read_poses(path) -> np.ndarray:
    """poses.txt -> (N, 4, 4) float64."""
    rows = []
    with open(path, encoding="ascii") as f:
        for number, line in enumerate(f, 1):
            if not line.strip():
                continue
            values = line.split()
            if len(values) != 12:
                raise ValueError(f"{path}:{number}: expected 12 numbers, found {len(values)}")
            rows.append([float(v) for v in values])
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    if rows:
        poses[:, :3, :] = np.asarray(rows).reshape(-1, 3, 4)
    return poses


def read_scan(path) -> np.ndarray:
    """velodyne/NNNNNN.bin -> (N, 4) float32 x, y, z, intensity."""
    data = np.fromfile(path, dtype="<f4")
    if data.size % 4 != 0:
        raise ValueError(f"{path}: {data.size * 4} bytes is not a multiple of 16 (x,y,z,i float32)")
    return data.reshape(-1, 4)


class KittiSequence:
    """The scans of a directory, in order: len(), seq[k] -> (points Nx4, pose 4x4), iteration."""

    def __init__(self, directory):
        self.directory = os.fspath(directory)
        scan_dir = os.path.join(self.directory, "velodyne")
        numbered = {}
        for name in os.listdir(scan_dir):
            m = _SCAN_NAME.match(name)
            if m:
                numbered[int(m.group(1))] = os.path.join(scan_dir, name)
        self.scan_paths = [numbered[k] for k in sorted(numbered)]
        if sorted(numbered) != list(range(len(numbered))):
            missing = next(k for k in range(len(numbered)) if k not in numbered)
            raise ValueError(f"{scan_dir}: scan {missing:06d}.bin is missing")
        self.poses = read_poses(os.path.join(self.directory, "poses.txt"))
        if len(self.poses) < len(self.scan_paths):
            raise ValueError(f"{self.directory}/poses.txt: {len(self.poses)} poses for "
                             f"{len(self.scan_paths)} scans")
        self.poses = self.poses[:len(self.scan_paths)]

    def __len__(self) -> int:
        return len(self.scan_paths)

    def __getitem__(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        return read_scan(self.scan_paths[k]), self.poses[k]

    def __iter__(self) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
        for k in range(len(self)):
            yield self[k]
