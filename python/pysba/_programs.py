# SPDX-License-Identifier: BSD-3-Clause
"""The programs pip installs with pysba: the console command `sbarefine` runs the C++ program
of that name, which setup.py builds and keeps in the package (pysba/bin) with the library it
links. Nothing of pysba's own runs: the command is the program, its options, output and exit
status (README.md, docs/formats.md)."""
import os
import sys


def sbarefine() -> None:
    program = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bin", "sbarefine")
    if not os.access(program, os.X_OK):
        sys.exit(f"sbarefine: {program} is missing: this pysba was built without its programs "
                 f"(the CMake build has them in build/demo)")
    # The process becomes the program: signals and the exit status are its own.
    os.execv(program, ["sbarefine", *sys.argv[1:]])
