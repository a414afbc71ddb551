"""`cmake --install --component python` gives a package that imports from the prefix alone."""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys


def test_installed_package_imports_from_the_prefix(tmp_path):
    prefix = tmp_path / "prefix"
    subprocess.run([os.environ["CMAKE_COMMAND"], "--install", os.environ["BGKMAP_BINARY_DIR"],
                    "--component", "python", "--prefix", str(prefix)],
                   check=True, capture_output=True, text=True, timeout=120)
    site = prefix / os.environ["BGKMAP_PYTHON_INSTALL_DIR"]
    assert (site / "bgkmap" / "v1" / "map_service_pb2_grpc.py").is_file()
    env = dict(os.environ, PYTHONPATH=str(site))
    probe = ("import bgkmap, bgkmap.v1.map_service_pb2_grpc as s; "
             "print(bgkmap.__file__); print(bgkmap.__version__); print(s.MapServiceStub.__name__)")
    out = subprocess.run([sys.executable, "-c", probe], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    path, version, stub = out.stdout.split()
    assert path.startswith(str(site)) and stub == "MapServiceStub"
    assert version == os.environ["BGKMAP_VERSION"]


def test_pip_installs_the_package_from_the_source_tree(tmp_path):
    """`pip install client/python` (pyproject.toml) builds the stubs from proto/ and gives the
    same package as the CMake build; no network (--no-index, Debian's setuptools)."""
    src = pathlib.Path(os.environ["BGKMAP_SOURCE_DIR"])
    tree = tmp_path / "src"  # a copy, so the build leaves nothing in the checkout
    shutil.copytree(src / "client" / "python", tree / "client" / "python",
                    ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    shutil.copytree(src / "proto" / "bgkmap", tree / "proto" / "bgkmap")
    shutil.copy(src / "CMakeLists.txt", tree / "CMakeLists.txt")
    target = tmp_path / "site"
    run = subprocess.run([sys.executable, "-m", "pip", "install", "--no-build-isolation",
                          "--no-deps", "--no-index", "--target", str(target),
                          str(tree / "client" / "python")],
                         capture_output=True, text=True, timeout=240)
    assert run.returncode == 0, run.stdout + run.stderr
    env = dict(os.environ, PYTHONPATH=str(target))
    probe = ("import bgkmap, bgkmap.v1.map_service_pb2_grpc as s; "
             "print(bgkmap.__file__); print(bgkmap.__version__); print(s.MapServiceStub.__name__)")
    out = subprocess.run([sys.executable, "-c", probe], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    path, version, stub = out.stdout.split()
    assert path.startswith(str(target)) and stub == "MapServiceStub"
    assert version == os.environ["BGKMAP_VERSION"]
