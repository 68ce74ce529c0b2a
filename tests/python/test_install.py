# SPDX-License-Identifier: BSD-3-Clause
"""`pip install --no-build-isolation .` from a copy of the source tree into a fresh venv,
then pysba imported from there, in a clean environment, solves a problem. Slow (it builds
the library): ctest runs it as a test of its own."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from conftest import DEMO, REPO, need

SCRIPT = """
import sys, pysba
problem = pysba.read_eucsbademo(sys.argv[1], sys.argv[2], sys.argv[3])
result = pysba.solve(problem)
print(pysba.__file__)
print(f"{result.final_mse:g} {result.iterations} {result.reason.name}")
"""


def test_pip_install_into_a_venv(tmp_path):
    data = [need(DEMO / "7cams.txt"), DEMO / "7pts.txt", DEMO / "calib.txt"]
    src = tmp_path / "src"
    # What a clean clone holds: no build trees, no caches.
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".git", "build", "build-*", "__pycache__",
                                                               "*.egg-info", ".pytest_cache"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LD_LIBRARY_PATH")}
    env.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", "2")
    env["PIP_NO_INDEX"] = "1"
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-build-isolation", str(src)], check=True,
                   env=env, cwd=tmp_path)
    shutil.rmtree(src)  # the installed package must not need the source tree
    out = subprocess.run([str(python), "-c", SCRIPT, *map(str, data)], check=True, env=env, cwd=tmp_path,
                         capture_output=True, text=True).stdout.split("\n")
    assert Path(out[0]).is_relative_to(venv)
    assert out[1] == "0.675396 17 STEP"
