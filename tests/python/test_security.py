"""The Python client over TLS (and mutual TLS) with a bearer token, against a real bgkmapd whose
certificates the openssl CLI makes for this module."""

from __future__ import annotations

import hashlib
import subprocess

import grpc
import numpy as np
import pytest

import bgkmap
from conftest import BgkmapdProcess


def _openssl(*args: str, cwd) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


@pytest.fixture(scope="module")
def pki(tmp_path_factory):
    d = tmp_path_factory.mktemp("pki")
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out",
             "ca.pem", "-days", "2", "-subj", "/CN=bgkmap test CA", cwd=d)
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out",
             "server.csr", "-subj", "/CN=localhost", cwd=d)
    (d / "san.ext").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    _openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
             "-CAcreateserial", "-out", "server.pem", "-days", "2", "-extfile", "san.ext", cwd=d)
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "client.key", "-out",
             "client.csr", "-subj", "/CN=planner", cwd=d)
    _openssl("x509", "-req", "-in", "client.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
             "-CAcreateserial", "-out", "client.pem", "-days", "2", cwd=d)
    digest = lambda token: hashlib.sha256(token.encode()).hexdigest()  # noqa: E731
    (d / "tokens.yaml").write_text(
        "tokens:\n"
        f"  - {{name: planner, sha256: {digest('planner-secret')}, role: planner}}\n"
        f"  - {{name: lidar, sha256: {digest('robot-secret')}, role: robot, robots: [r1]}}\n")
    return d


@pytest.fixture(scope="module")
def mtls_server(pki):
    server = BgkmapdProcess("--set", f"server.tls.cert_file={pki / 'server.pem'}",
                            "--set", f"server.tls.key_file={pki / 'server.key'}",
                            "--set", f"server.tls.client_ca_file={pki / 'ca.pem'}",
                            "--set", f"server.auth.tokens_file={pki / 'tokens.yaml'}")
    yield server
    assert server.stop() == 0, "\n".join(server.lines[-20:])


def _client(server, pki, **options) -> bgkmap.Client:
    options.setdefault("timeout", 10.0)
    return bgkmap.Client(server.target, **options)


def test_tls_with_client_certificate_and_token_works(mtls_server, pki):
    with _client(mtls_server, pki, tls_ca=str(pki / "ca.pem"), tls_cert=str(pki / "client.pem"),
                 tls_key=str(pki / "client.key"), token="planner-secret") as c:
        assert c.info()["map_version"] == 0
        region = c.query((0, 0, 2, 2))
        assert region is not None


def test_missing_token_is_unauthenticated_and_a_role_is_enforced(mtls_server, pki):
    tls = dict(tls_ca=str(pki / "ca.pem"), tls_cert=str(pki / "client.pem"),
               tls_key=str(pki / "client.key"))
    with _client(mtls_server, pki, token="", **tls) as c:
        with pytest.raises(bgkmap.BgkmapError) as e:
            c.info()
        assert e.value.code == grpc.StatusCode.UNAUTHENTICATED
    with _client(mtls_server, pki, token="planner-secret", **tls) as c:
        points = np.zeros((10, 3), dtype=np.float32)
        with pytest.raises(bgkmap.BgkmapError) as e:
            c.insert(points, np.eye(4), robot="r1", seq=1)
        assert e.value.code == grpc.StatusCode.PERMISSION_DENIED
        assert "role planner" in e.value.message


def test_token_from_the_environment(mtls_server, pki, monkeypatch):
    monkeypatch.setenv("BGKMAP_TOKEN", "planner-secret")
    with _client(mtls_server, pki, tls_ca=str(pki / "ca.pem"), tls_cert=str(pki / "client.pem"),
                 tls_key=str(pki / "client.key")) as c:
        assert c.info()["map_version"] == 0


def test_without_client_certificate_or_without_tls_the_call_fails(mtls_server, pki):
    with _client(mtls_server, pki, tls_ca=str(pki / "ca.pem"), token="planner-secret") as c:
        with pytest.raises(bgkmap.BgkmapError) as e:
            c.info()
        assert e.value.code == grpc.StatusCode.UNAVAILABLE
    with _client(mtls_server, pki, token="planner-secret") as c:
        with pytest.raises(bgkmap.BgkmapError) as e:
            c.info()
        assert e.value.code == grpc.StatusCode.UNAVAILABLE


def test_tls_arguments_are_checked(pki):
    with pytest.raises(ValueError, match="go together"):
        bgkmap.Client("127.0.0.1:1", tls_ca=str(pki / "ca.pem"), tls_cert=str(pki / "client.pem"))
    with pytest.raises(ValueError, match="needs tls_ca"):
        bgkmap.Client("127.0.0.1:1", tls_cert=str(pki / "client.pem"),
                      tls_key=str(pki / "client.key"))
