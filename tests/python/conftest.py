"""Fixtures of the Python client's tests: a real bgkmapd on a free loopback port, the street scans.

CTest runs these with PYTHONPATH set to the build's python/ folder and the paths below in the
environment (tests/python/CMakeLists.txt). Every module the client needs is imported here at
once, so a missing Debian package (python3-grpcio, python3-protobuf, python3-numpy) fails the
run loudly instead of skipping tests.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time

import grpc  # noqa: F401  (python3-grpcio)
import google.protobuf  # noqa: F401  (python3-protobuf)
import numpy  # noqa: F401  (python3-numpy)
import pytest

import bgkmap

_LISTENING = re.compile(r"event=listening .*port=(\d+)")


def _env(name: str) -> str:
    value = os.environ.get(name)
    if not value:
        raise RuntimeError(f"${name} is not set: run these tests through ctest "
                           "(tests/python/CMakeLists.txt sets it)")
    return value


class BgkmapdProcess:
    """`bgkmapd --listen 127.0.0.1:0 <args>`, started and waited for ("event=listening")."""

    def __init__(self, *args: str, start_timeout: float = 30.0):
        self.lines: list = []
        self.port = 0
        self._listening = threading.Event()
        self.process = subprocess.Popen(
            [_env("BGKMAPD"), "--listen", "127.0.0.1:0", *args],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True)
        self._reader = threading.Thread(target=self._read_log, daemon=True)
        self._reader.start()
        if not self._listening.wait(start_timeout):
            self.kill()
            raise RuntimeError("bgkmapd did not start:\n" + "\n".join(self.lines))

    def _read_log(self) -> None:
        for line in self.process.stderr:
            self.lines.append(line.rstrip("\n"))
            m = _LISTENING.search(line)
            if m and not self.port:
                self.port = int(m.group(1))
                self._listening.set()

    @property
    def target(self) -> str:
        return f"127.0.0.1:{self.port}"

    def client(self, **options) -> bgkmap.Client:
        options.setdefault("timeout", 30.0)
        return bgkmap.Client(self.target, **options)

    def stop(self, timeout: float = 30.0) -> int:
        """SIGTERM, then the exit code (SIGKILL after `timeout` seconds)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            code = self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise RuntimeError("bgkmapd did not stop within %.0f s" % timeout)
        self._reader.join(5)
        return code

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


def street_dir() -> str:
    return os.path.join(_env("BGKMAP_SHARED_DATA"), "ouster_os1_128_street")


@pytest.fixture(scope="session")
def street() -> bgkmap.KittiSequence:
    """The real Ouster OS1-128 street scans (3 scans, KITTI layout)."""
    return bgkmap.KittiSequence(street_dir())


@pytest.fixture
def fresh_server():
    """A bgkmapd of its own for one test, empty."""
    server = BgkmapdProcess()
    yield server
    assert server.stop() == 0, "\n".join(server.lines[-20:])


@pytest.fixture(scope="module")
def street_server(street):
    """A bgkmapd holding the street scans of robot "street", inserted one by one (IngestScan)."""
    server = BgkmapdProcess()
    with server.client() as client:
        for k, (points, pose) in enumerate(street):
            ack = client.insert(points, pose, robot="street", seq=k + 1, stamp=time.time())
            assert ack.status == "applied", ack
    yield server
    assert server.stop() == 0, "\n".join(server.lines[-20:])


@pytest.fixture
def client(street_server):
    with street_server.client() as c:
        yield c
