#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Draws a series of bench/series.sh: bench/results/NAME_series.{dat,gp,png}, time per
iteration and peak RSS against the observations, one line per run kind.

    bench/plot_series.py orbit|photo
"""
import json
import os
import shutil
import sys

import run_suite

TITLES = {
    "orbit": "Orbit series (sbagen orbit, fixed K, 100 points per camera, tracks 3..40)",
    "photo": "Photo-collection series (sbagen photo, fixed K, 100 points per camera, tracks from 4)",
}


def main():
    if len(sys.argv) != 2 or sys.argv[1] not in TITLES:
        sys.exit("usage: bench/plot_series.py %s" % "|".join(TITLES))
    name = sys.argv[1]
    results = os.path.join(run_suite.HERE, "results")
    with open(os.path.join(results, name + "_series.json")) as f:
        runs = [json.loads(line) for line in f if line.strip()]
    png = run_suite.plot_runs(results, name + "_series", TITLES[name], runs, shutil.which("gnuplot"))
    if png:
        print("plot_series: wrote %s" % png)


if __name__ == "__main__":
    main()
