# SPDX-License-Identifier: BSD-3-Clause
"""Builds pysba's extension module with the project's CMake build (pyproject.toml has the
metadata): the library is compiled into the module, so the installed package needs no
libsba.so and no LD_LIBRARY_PATH. The sbarefine program is built too, and kept in the package
with the libsba.so it links, beside it (pysba/bin): pip's `sbarefine` command runs it."""
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def library_version():
    """The library's version, as sba.h's SBA_VERSION ends with it ("(sba-cpp 0.1.0)"): the
    version the programs' --version and pysba.__version__ give."""
    found = re.search(r'#define SBA_VERSION ".*\(sba-cpp ([^)]+)\)"', (ROOT / "sba.h").read_text())
    if not found:
        raise RuntimeError("sba.h: no version in SBA_VERSION")
    return found.group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = Path(self.build_temp).resolve() / "cmake"
        build.mkdir(parents=True, exist_ok=True)
        # CMAKE_ARGS: more options for the configure step, as for other CMake-built packages
        # (e.g. -DCMAKE_BUILD_TYPE=RelWithDebInfo, or -DCMAKE_IGNORE_PATH=... to keep an
        # installed pybind11 out of the search).
        extra = shlex.split(os.environ.get("CMAKE_ARGS", ""))
        # The programs find libsba.so in their own folder ($ORIGIN), where the package keeps
        # sbarefine and the library, whichever folder pip installs the package into.
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                        "-DSBA_BUILD_PYTHON=ON", "-DSBA_BUILD_TESTS=OFF", "-DSBA_BUILD_DEMO=ON",
                        "-DSBA_BUILD_MEX=OFF", "-DSBA_BUILD_BENCH=OFF", "-DCMAKE_INSTALL_RPATH=$ORIGIN",
                        "-DCMAKE_BUILD_WITH_INSTALL_RPATH=ON", f"-DPython_EXECUTABLE={sys.executable}", *extra],
                       check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build), "--target", "_core", "sbarefine", "-j", jobs], check=True)
        built = sorted((build / "python" / "pkg" / "pysba").glob("_core*.so")) + \
            sorted((build / "python" / "pkg" / "pysba").glob("_core*.pyd"))
        if not built:
            raise RuntimeError(f"CMake built no _core module in {build}")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[0], target)
        programs = target.parent / "bin"
        programs.mkdir(exist_ok=True)
        # The library by its SONAME (SOVERSION 1), the name the program asks the loader for.
        for made, name in ((build / "demo" / "sbarefine", "sbarefine"), (build / "libsba.so.1", "libsba.so.1")):
            if not made.exists():
                raise RuntimeError(f"CMake built no {made}")
            shutil.copy(made, programs / name)


setup(version=library_version(), ext_modules=[Extension("pysba._core", sources=[])],
      cmdclass={"build_ext": CMakeBuild})
