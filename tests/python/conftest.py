# SPDX-License-Identifier: BSD-3-Clause
"""Shared fixtures of the pysba tests: where the reference data is, and the problems on it.

PYSBA_DATA_DIR (set by ctest) names ../shared/data; tests that need it skip when it is
absent, as the C++ tests do."""
import os
from pathlib import Path

import pytest

import pysba

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("PYSBA_DATA_DIR", REPO.parent / "shared" / "data"))
DEMO = DATA / "sba-demo"
BAL = DATA / "bal"


# The sanitizer build (make check-sanitize: -O1, instrumented) rounds differently from the
# optimized one, so the figures a test states for the optimized build (iterations, errors)
# are checked only there; comparisons with the programs of the same build hold in both.
OPTIMIZED = not os.environ.get("PYSBA_SANITIZED")


def need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"reference data {path} is absent")
    return path


@pytest.fixture
def cams54():
    return pysba.read_eucsbademo(need(DEMO / "54cams.txt"), DEMO / "54pts.txt", DEMO / "calib.txt")


@pytest.fixture
def cams7():
    return pysba.read_eucsbademo(need(DEMO / "7cams.txt"), DEMO / "7pts.txt", DEMO / "calib.txt")


@pytest.fixture
def bal21():
    return pysba.read_bal(need(BAL / "problem-21-11315-pre.txt.bz2"))
