# SPDX-License-Identifier: BSD-3-Clause
"""pip install into a fresh venv by both routes of docs/python.md; then pysba imported from
there, in a clean environment, solves a problem, its version is the package's, and the venv's
sbarefine command runs the program. Slow (each builds the library): ctest runs each route as a
test of its own (python_install_local, python_install_index), each route taken once.

- --no-build-isolation: `pip install .` of a copy of the source tree, with what is installed
  (Debian's setuptools, wheel, pybind11-dev).
- with build isolation: `pip install` of an sdist of that copy (which must hold everything the
  build needs), pip installing pyproject.toml's build requirements into a build environment
  of its own: from the package index, into a venv of the python3 first on PATH with nothing
  of the system's. Where the index cannot be reached, from a wheelhouse:
  Debian's setuptools and wheel .whl files, and a wheel of Debian's python3-pybind11
  distribution (the pybind11 package as pip installs it). Debian's pybind11 CMake files are
  hidden from CMake, so the build must find pybind11 through the build environment's
  `python -m pybind11 --cmakedir`, as on a machine without pybind11-dev."""
import base64
import hashlib
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from conftest import DEMO, REPO, need

SCRIPT = """
import importlib.metadata, sys, pysba
problem = pysba.read_eucsbademo(sys.argv[1], sys.argv[2], sys.argv[3])
result = pysba.solve(problem)
print(pysba.__file__)
print(f"{result.final_mse:g} {result.iterations} {result.reason.name}")
print(importlib.metadata.version("pysba"), pysba.__version__, pysba.SBA_VERSION)
"""

WHEELS = Path("/usr/share/python-wheels")


def install_and_solve(tmp_path, pip_args, extra_env=None, base=sys.executable, index=False, sdist=False):
    """pip install (pip_args) a clean copy of the tree into a new venv of the Python base
    (with its system site packages unless the package index is used: then every package comes
    from there), or with sdist the source distribution setuptools makes of that copy; delete
    the copy, and solve 7cams with the installed package. Returns pip's output (its standard
    output and error: where the build's lines go depends on pip's version)."""
    data = [need(DEMO / "7cams.txt"), DEMO / "7pts.txt", DEMO / "calib.txt"]
    src = tmp_path / "src"
    # What a clean clone holds: no build trees, no caches.
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".git", "build", "build-*", "__pycache__",
                                                               "*.egg-info", ".pytest_cache"))
    venv = tmp_path / "venv"
    subprocess.run([base, "-m", "venv", *([] if index else ["--system-site-packages"]), str(venv)], check=True)
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LD_LIBRARY_PATH", "LD_PRELOAD")}
    env.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", "2")
    if not index:
        env["PIP_NO_INDEX"] = "1"
    env.update(extra_env or {})
    target = src
    if sdist:
        # PEP 517's hook, as `python -m build --sdist` calls it, with this interpreter's
        # setuptools (a venv without the system's packages may have none).
        made = subprocess.run([sys.executable, "-c", "import sys; from setuptools import build_meta; "
                               "print(build_meta.build_sdist(sys.argv[1]))", str(tmp_path / "dist")],
                              env=env, cwd=src, capture_output=True, text=True)
        assert made.returncode == 0, made.stdout[-4000:] + made.stderr[-4000:]
        target = tmp_path / "dist" / made.stdout.split()[-1]
    pip = subprocess.run([str(python), "-m", "pip", "install", "-v", *pip_args, str(target)], env=env,
                         cwd=tmp_path, capture_output=True, text=True)
    assert pip.returncode == 0, pip.stdout[-4000:] + pip.stderr[-4000:]
    # The installed package must not need the source tree.
    shutil.rmtree(src)
    shutil.rmtree(tmp_path / "dist", ignore_errors=True)
    out = subprocess.run([str(python), "-c", SCRIPT, *map(str, data)], check=True, env=env, cwd=tmp_path,
                         capture_output=True, text=True).stdout.split("\n")
    assert Path(out[0]).is_relative_to(venv)
    assert out[1] == "0.675396 17 STEP"
    version, library_version, sba_version = out[2].split(" ", 2)
    assert version == library_version
    check_sbarefine(venv, env, tmp_path, sba_version)
    return pip.stdout + pip.stderr


def check_sbarefine(venv, env, tmp_path, sba_version):
    """The venv's sbarefine command is the program (its --version), and refines a model of the
    build's sbagen (when ctest names it) to the minimum the build's sbarefine reaches. pip
    compiles with its own flags (another optimization level than a Debug or RelWithDebInfo
    build), and where the run stops near the minimum moves with the rounding: the errors as
    printed (six digits) are the problem's, the iteration count and stop reason are not."""
    command = venv / "bin" / "sbarefine"
    version = subprocess.run([str(command), "--version"], env=env, capture_output=True, text=True, check=True)
    assert version.stdout.startswith(f"sbarefine (sba {sba_version})"), version.stdout
    sbagen, built = os.environ.get("PYSBA_SBAGEN"), os.environ.get("PYSBA_SBAREFINE")
    if not sbagen or not built:
        return
    subprocess.run([sbagen, "--cameras", "6", "--points", "60", "--quiet", "--out", str(tmp_path / "g"),
                    "--colmap", str(tmp_path / "model")], check=True)
    lines = []
    for k, exe in enumerate((str(command), built)):
        run = subprocess.run([exe, str(tmp_path / "model"), "--threads", "1", "--write", str(tmp_path / f"out{k}")],
                             env=env, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        lines.append([line for line in run.stdout.splitlines() if line.startswith("SBA returned")])
    assert len(lines[0]) == 1 and len(lines[1]) == 1, lines
    errors = [re.search(r"error \S+ \[initial \S+\]", found[0]) for found in lines]
    assert errors[0] and errors[1] and errors[0].group(0) == errors[1].group(0), lines


def test_pip_install_without_build_isolation(tmp_path):
    install_and_solve(tmp_path, ["--no-build-isolation"])


def wheel_of_installed(name, wheelhouse):
    """A wheel of the installed distribution `name` (pure Python, as Debian installs it from
    its upstream wheel): its files under site-packages, RECORD made anew."""
    dist = importlib.metadata.distribution(name)
    site = Path(dist.locate_file(""))
    files = sorted({str(f) for f in dist.files if not str(f).startswith("..") and not str(f).endswith("RECORD")})
    info = next(f.split("/")[0] for f in files if f.endswith(".dist-info/METADATA"))
    path = wheelhouse / f"{name}-{dist.version}-py3-none-any.whl"
    record = []
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as whl:
        for f in files:
            body = (site / f).read_bytes()
            digest = base64.urlsafe_b64encode(hashlib.sha256(body).digest()).rstrip(b"=").decode()
            record.append(f"{f},sha256={digest},{len(body)}")
            whl.writestr(f, body)
        whl.writestr(f"{info}/RECORD", "\n".join(record + [f"{info}/RECORD,,"]) + "\n")
    return path


def index_reachable(url="https://pypi.org/simple/pybind11/"):
    """Whether pip's package index answers (a machine without network skips the test)."""
    import urllib.request
    index = os.environ.get("PIP_INDEX_URL")
    try:
        with urllib.request.urlopen(index.rstrip("/") + "/pybind11/" if index else url, timeout=20) as r:
            return r.status == 200
    except OSError:
        return False


def test_pip_install_with_build_isolation(tmp_path):
    if shutil.which("python3") and index_reachable():
        pytest.skip("build isolation is tested from the package index "
                    "(test_pip_install_from_the_index_with_the_python_on_path)")
    wheels = [next(WHEELS.glob(f"{n}-*.whl"), None) for n in ("setuptools", "wheel")]
    try:
        importlib.metadata.distribution("pybind11")
    except importlib.metadata.PackageNotFoundError:
        wheels.append(None)
    if None in wheels:
        pytest.skip("needs Debian's python3-setuptools-whl, python3-wheel-whl and python3-pybind11 "
                    "(scripts/deps.sh python)")
    wheelhouse = tmp_path / "wheelhouse"
    wheelhouse.mkdir()
    for w in wheels:
        shutil.copy(w, wheelhouse)
    wheel_of_installed("pybind11", wheelhouse)
    # Debian's pybind11 CMake files (pybind11-dev's and python3-pybind11's) out of the search.
    debian = ["/usr/lib/cmake/pybind11", "/usr/share/cmake/pybind11",
              "/usr/lib/python3/dist-packages/pybind11/share/cmake/pybind11"]
    out = install_and_solve(tmp_path, ["--find-links", str(wheelhouse)],
                            {"CMAKE_ARGS": "-DCMAKE_IGNORE_PATH=" + ";".join(debian)}, sdist=True)
    found = [line for line in out.splitlines() if "sba: pybind11" in line]
    # From the isolated build environment pip made: not Debian's, not the venv's.
    assert len(found) == 1 and "/pip-build-env-" in found[0] and "/share/cmake/pybind11" in found[0], \
        found or out[-4000:]


def test_pip_install_from_the_index_with_the_python_on_path(tmp_path):
    # What a user of another Python (pyenv, conda, python.org) types: `pip install` in a
    # fresh venv, the build requirements and numpy from the package index. From an sdist,
    # which holds only what MANIFEST.in adds to setuptools' defaults: the build must find the
    # library's sources, headers and CMake files in it.
    base = shutil.which("python3")
    if base is None:
        pytest.skip("no python3 on PATH")
    if not index_reachable():
        pytest.skip("the package index is not reachable")
    out = install_and_solve(tmp_path, [], base=base, index=True, sdist=True)
    found = [line for line in out.splitlines() if "sba: pybind11" in line]
    assert len(found) == 1 and "/pip-build-env-" in found[0], found or out[-4000:]
