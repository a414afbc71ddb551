#!/usr/bin/env python3
"""A small path planner on a bgkmap server: query traversability around start and goal, run A* on
it, shorten the path to the waypoints where it turns, then ask the server whether the robot's
footprint is safe along it (at the waypoints and on the straight segments between them).

    PYTHONPATH=build/python /usr/bin/python3 client/python/examples/astar_planner.py \\
        --server 127.0.0.1:50051 --start -8 -2 --goal 8 2 --radius 0.3

Prints the plan as JSON (metres) and exits 0 when a safe path was found, 1 when there is none
(or the server judged it unsafe), 2 on usage errors. docs/python.md walks through it.
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import sys

import numpy as np

import bgkmap


def free_space(region: bgkmap.Region, radius: float) -> np.ndarray:
    """Pixels where a disk of `radius` around the centre lies on known, traversable ground.

    state is 1 for traversable (traversability and its variance below the map's thresholds), 2
    for non-traversable, 0 for unknown. Obstacles and unknown cells are grown by the radius plus
    half a pixel diagonal, so the footprint check of the server agrees with the plan."""
    blocked = region["state"] != 1
    reach = int(math.ceil(radius / region.resolution + math.sqrt(0.5)))
    grown = blocked.copy()
    rows, cols = blocked.shape
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            if dr * dr + dc * dc > reach * reach:
                continue
            shifted = np.ones_like(blocked)  # beyond the raster: unknown
            src = blocked[max(0, -dr):rows - max(0, dr), max(0, -dc):cols - max(0, dc)]
            shifted[max(0, dr):max(0, dr) + src.shape[0], max(0, dc):max(0, dc) + src.shape[1]] = src
            grown |= shifted
    return ~grown


def astar(free: np.ndarray, cost: np.ndarray, start: tuple, goal: tuple):
    """8-connected A* over pixels; step cost = length x (1 + cost of the entered pixel).
    Returns the list of (row, col) from start to goal, or None."""
    rows, cols = free.shape
    moves = [(dr, dc, math.hypot(dr, dc)) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]

    def h(p):  # octile distance: admissible, since every step costs at least its length
        dr, dc = abs(p[0] - goal[0]), abs(p[1] - goal[1])
        return max(dr, dc) + (math.sqrt(2) - 1) * min(dr, dc)

    g = {start: 0.0}
    came = {}
    frontier = [(h(start), 0.0, start)]
    while frontier:
        _, dist, p = heapq.heappop(frontier)
        if p == goal:
            path = [p]
            while p in came:
                p = came[p]
                path.append(p)
            return path[::-1]
        if dist > g[p]:
            continue  # a stale entry
        for dr, dc, length in moves:
            q = (p[0] + dr, p[1] + dc)
            if not (0 <= q[0] < rows and 0 <= q[1] < cols) or not free[q]:
                continue
            if dr and dc and not (free[p[0] + dr, p[1]] and free[p[0], p[1] + dc]):
                continue  # no corner cutting
            nd = dist + length * (1.0 + cost[q])
            if nd < g.get(q, math.inf):
                g[q] = nd
                came[q] = p
                heapq.heappush(frontier, (nd + h(q), nd, q))
    return None


def line_is_free(free: np.ndarray, a, b) -> bool:
    """True when the straight line between pixel centres a and b (row, col) crosses free pixels
    only, sampled every quarter pixel."""
    n = int(math.ceil(4 * math.hypot(b[0] - a[0], b[1] - a[1]))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    rows = np.rint(a[0] + t * (b[0] - a[0])).astype(int)
    cols = np.rint(a[1] + t * (b[1] - a[1])).astype(int)
    return bool(np.all(free[rows, cols]))


def shorten(free: np.ndarray, cells: list) -> list:
    """The waypoints of an A* path: from each kept cell, jump to the farthest later cell in a
    straight line over free pixels. The server checks the segments between waypoints, so a
    planner need not send every cell."""
    kept = [0]
    while kept[-1] < len(cells) - 1:
        i = kept[-1]
        j = len(cells) - 1
        while j > i + 1 and not line_is_free(free, cells[i], cells[j]):
            j -= 1
        kept.append(j)
    return [cells[k] for k in kept]


def plan(client: bgkmap.Client, start, goal, radius: float = 0.3, stride: int = 1,
         margin: float = 10.0, cost_weight: float = 4.0) -> dict:
    """Plans from start (x, y) to goal (x, y) on the served map. The dict says whether a path was
    found, the waypoints (x, y, yaw; the path is the straight segments between them), its length
    and the server's footprint check (with the first unsafe point when it is not safe)."""
    box = (min(start[0], goal[0]) - margin, min(start[1], goal[1]) - margin,
           max(start[0], goal[0]) + margin, max(start[1], goal[1]) + margin)
    region = client.query(box, layers=["traversability", "state"], stride=stride)
    free = free_space(region, radius)
    cost = np.nan_to_num(region["traversability"], nan=1.0) * cost_weight
    (sr, gr), (sc, gc) = region.index([start[0], goal[0]], [start[1], goal[1]])
    result = {"start": list(start), "goal": list(goal), "radius": radius,
              "resolution": region.resolution, "map_version": region.map_version,
              "found": False, "safe": False, "path": [], "length": None}
    if not (free[sr, sc] and free[gr, gc]):
        result["reason"] = "start or goal is not on free ground"
        return result
    cells = astar(free, cost, (int(sr), int(sc)), (int(gr), int(gc)))
    if cells is None:
        result["reason"] = "no path on known traversable ground"
        return result
    rows, cols = np.array(shorten(free, cells)).T
    x, y = region.xy(rows, cols)
    yaw = np.arctan2(np.diff(y, append=y[-1]), np.diff(x, append=x[-1]))
    if len(yaw) > 1:
        yaw[-1] = yaw[-2]
    poses = np.column_stack([x, y, yaw])
    check = client.check_path(poses, radius=radius)
    result.update(found=True, safe=check.safe, path=poses.round(3).tolist(),
                  length=float(np.sum(np.hypot(np.diff(x), np.diff(y)))),
                  first_unsafe_index=check.first_unsafe_index,
                  first_unsafe_point=check.first_unsafe_point)
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--server", default=None,
                        help="bgkmapd host:port (default: $BGKMAP_SERVER, else 127.0.0.1:50051)")
    parser.add_argument("--start", type=float, nargs=2, metavar=("X", "Y"), required=True,
                        help="start, metres")
    parser.add_argument("--goal", type=float, nargs=2, metavar=("X", "Y"), required=True,
                        help="goal, metres")
    parser.add_argument("--radius", type=float, default=0.3, help="robot disk radius, metres")
    parser.add_argument("--stride", type=int, default=1,
                        help="map cells per planning pixel (coarser is faster; see docs/python.md)")
    args = parser.parse_args(argv)
    try:
        with bgkmap.Client(args.server, timeout=60) as client:
            result = plan(client, args.start, args.goal, radius=args.radius, stride=args.stride)
    except bgkmap.BgkmapError as e:
        print(f"astar_planner: {e}", file=sys.stderr)
        return 1
    print(json.dumps(result, indent=2))
    return 0 if result["found"] and result["safe"] else 1


if __name__ == "__main__":
    sys.exit(main())
