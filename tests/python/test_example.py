"""The A* planner example of docs/python.md, run as a user runs it, on the street map."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

import bgkmap

SCRIPT = os.path.join(os.environ.get("BGKMAP_SOURCE_DIR", ""), "client", "python", "examples",
                      "astar_planner.py")


def run(*args: str, server) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, SCRIPT, "--server", server.target, *args],
                          capture_output=True, text=True, timeout=120)


def test_planner_finds_a_path_the_server_judges_safe(street_server):
    run_ = run("--start", "-8", "-2", "--goal", "8", "2", "--radius", "0.3", server=street_server)
    assert run_.returncode == 0, run_.stdout + run_.stderr
    plan = json.loads(run_.stdout)
    assert plan["found"] and plan["safe"] and plan["first_unsafe_index"] is None
    path = np.array(plan["path"])
    assert np.hypot(*(path[0, :2] - (-8, -2))) < plan["resolution"]
    assert np.hypot(*(path[-1, :2] - (8, 2))) < plan["resolution"]
    # Around the unknown ground near the sensor, not through it.
    assert plan["length"] > np.hypot(16, 4) + 1
    # Waypoints where the path turns, not one per cell: the server checks the segments between.
    assert 2 <= len(path) < plan["length"] / plan["resolution"] / 4
    # Every waypoint and every point on the segments between them is on traversable ground, as
    # the server says.
    along = np.concatenate([np.linspace(a[:2], b[:2], 50) for a, b in zip(path[:-1], path[1:])])
    with street_server.client() as client:
        state = client.points(along, layers=["state"])["state"]
        assert np.all(state == 1)
        check = client.check_path(path, radius=0.3)
        assert check.safe and np.all(check.segments["safe"])
        assert np.sum(check.segments["placement_count"]) > len(path)


def test_planner_reports_no_path_into_the_unknown(street_server):
    run_ = run("--start", "-8", "-2", "--goal", "0", "500", server=street_server)
    assert run_.returncode == 1, run_.stdout + run_.stderr
    plan = json.loads(run_.stdout)
    assert not plan["found"] and "goal" in plan["reason"]


def test_planner_usage_errors_exit_2(street_server):
    run_ = run("--start", "3", "--goal", "8", "2", server=street_server)
    assert run_.returncode == 2 and "--start" in run_.stderr, run_.stderr
