#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against `colmap bundle_adjuster` on shared-camera scenes of sbagen.

Each scene: sbagen --kind fixed (one PINHOLE camera for every image), its focal length
started 2% long, converted to a binary model by `colmap model_converter` (the input is one
COLMAP wrote). Two configurations, each program run --repeat times on the same input into a
fresh directory under /usr/bin/time -v:
  default  both programs at their defaults (each refines the shared fx and fy, the poses and
           the points);
  held     the intrinsics held by both (COLMAP --BundleAdjustment.refine_focal_length 0
           --BundleAdjustment.refine_extra_params 0, sbarefine --intrinsics none): the same
           problem for both.
Reported: the median of the wall times (and all of them), the largest peak RSS, the
iterations, and the RMS reprojection error of the written model measured by one yardstick
for both (tests/colmap_real/colmap_real.py's projection of COLMAP's camera models).

Threads: COLMAP 3.8's bundle_adjuster has no option for them (Ceres gets every hardware
thread); sbarefine is given --threads THREADS (default 2, this machine's core count).

  bench/colmap_ba.py --sbagen build/data/sbagen --sbarefine build/demo/sbarefine \\
      [--colmap colmap] [--sizes 100,300,1000] [--repeat 3] [--threads 2] [--configs default,held] \\
      [--points-per-image 100] [--out bench/results/colmap_ba] [--work DIR]
writes OUT.md (the tables and the exact commands) and OUT.json (one JSON object a run).
"""
import argparse
import datetime
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ left in the source tree by the import below
sys.path.insert(0, os.path.join(HERE, "..", "tests", "colmap_real"))
import colmap_real  # noqa: E402  (the yardstick and the model readers)


def timed(cmd, log):
    """Runs cmd under /usr/bin/time -v: (exit status, wall seconds, peak RSS in MiB, output)."""
    t0 = time.monotonic()
    r = subprocess.run(["/usr/bin/time", "-v"] + cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.monotonic() - t0
    with open(log, "w", encoding="utf-8") as f:
        f.write(" ".join(cmd) + "\n" + r.stdout)
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stdout)
    st = re.search(r"Exit status: (\d+)", r.stdout)
    status = int(st.group(1)) if st else r.returncode
    return status, wall, int(m.group(1)) / 1024.0 if m else float("nan"), r.stdout


def iterations(program, out):
    m = (re.search(r"SBA returned \S+ in (\d+) iter", out) if program == "sbarefine"
         else re.search(r"Iterations : (\d+)", out))
    return int(m.group(1)) if m else None


def refusal(out):
    """The program's own message, without /usr/bin/time's report."""
    lines = [ln for ln in out.splitlines() if ln.strip() and not ln.startswith("\t")
             and "Command exited with non-zero status" not in ln]
    return lines[-1] if lines else ""


def make_scene(a, n, work):
    d = os.path.join(work, "scene%d" % n)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    gen = os.path.join(d, "sbagen_text")
    cmd = [a.sbagen, "--out", os.path.join(d, "gen"), "--colmap", gen, "--kind", "fixed", "--cameras", str(n),
           "--points", str(n * a.points_per_image), "--seed", "36", "--quiet"]
    subprocess.run(cmd, check=True)
    m = colmap_real.read_text_model(gen)
    colmap_real.edit_shared(m)
    edited = os.path.join(d, "edited_text")
    colmap_real.write_text_model(m, edited)
    inp = os.path.join(d, "input")
    os.makedirs(inp)
    subprocess.run([a.colmap, "model_converter", "--input_path", edited, "--output_path", inp, "--output_type", "BIN"],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return d, inp, cmd


def commands(a, config, inp, out):
    colmap = [a.colmap, "bundle_adjuster", "--input_path", inp, "--output_path", out]
    sba = [a.sbarefine, inp, "--write", out, "--threads", str(a.threads)]
    if config == "held":
        colmap += ["--BundleAdjustment.refine_focal_length", "0", "--BundleAdjustment.refine_extra_params", "0"]
        sba += ["--intrinsics", "none"]
    return {"colmap": colmap, "sbarefine": sba}


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sbagen", required=True)
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--colmap", default=shutil.which("colmap") or "/usr/bin/colmap")
    ap.add_argument("--sizes", default="100,300,1000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--points-per-image", type=int, default=100)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "colmap_ba"))
    ap.add_argument("--configs", default="default,held", help="which configurations, comma-separated")
    ap.add_argument("--work", help="scenes and outputs here, kept (default: a temporary directory, removed)")
    a = ap.parse_args(argv)
    if not os.access(a.colmap, os.X_OK):
        print("colmap_ba: no colmap program at %s" % a.colmap, file=sys.stderr)
        return 1
    work = a.work or tempfile.mkdtemp(prefix="colmap_ba.")
    os.makedirs(work, exist_ok=True)
    version = subprocess.run([a.colmap, "-h"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True).stdout.strip().splitlines()[0]
    runs, rows, cmds = [], [], []
    try:
        for n in [int(s) for s in a.sizes.split(",")]:
            d, inp, gen_cmd = make_scene(a, n, work)
            scene = colmap_real.read_model(inp)
            rms0, nobs = colmap_real.rms_error(scene)
            cmds.append(" ".join(gen_cmd).replace(work, "$WORK") + "   # then the focal length * 1.02, colmap model_converter to BIN")
            print("colmap_ba: %d images, %d points, %d observations, initial RMS %.4f px"
                  % (n, len(scene.points), nobs, rms0), flush=True)
            for config in a.configs.split(","):
                for program in ("colmap", "sbarefine"):
                    walls, rss, status, out, its = [], [], 0, "", None
                    outdir = os.path.join(d, "%s_%s" % (config, program))
                    for k in range(a.repeat):
                        shutil.rmtree(outdir, ignore_errors=True)
                        os.makedirs(outdir)
                        cmd = commands(a, config, inp, outdir)[program]
                        load = os.getloadavg()[0]
                        status, wall, peak, out = timed(cmd, outdir + ".log%d" % k)
                        its = iterations(program, out)
                        if k == 0:
                            cmds.append(" ".join(cmd).replace(work, "$WORK"))
                        runs.append({"images": n, "points": len(scene.points), "observations": nobs,
                                     "config": config, "program": program, "run": k, "exit": status,
                                     "wall_s": round(wall, 3), "peak_rss_mib": round(peak, 1),
                                     "iterations": its, "load_avg_1min": load, "command": " ".join(cmd)})
                        if status != 0:
                            break
                        walls.append(wall)
                        rss.append(peak)
                    row = {"images": n, "observations": nobs, "config": config, "program": program,
                           "rms0": rms0, "exit": status}
                    if status == 0:
                        result = colmap_real.read_model(outdir)
                        row.update(median=statistics.median(walls), walls=walls, rss=max(rss), iterations=its,
                                   rms=colmap_real.rms_error(result)[0],
                                   focal=result.cameras[min(result.cameras)][3][0])
                        runs[-1]["rms"] = row["rms"]
                    else:
                        row["why"] = refusal(out).replace(work, "$WORK")
                    rows.append(row)
                    print("  %-8s %-9s %s" % (config, program, "median %.2f s, %.0f MiB, RMS %.6f px, %s iterations"
                                               % (row["median"], row["rss"], row["rms"], its)
                                               if status == 0 else "exit %d: %s" % (status, row["why"])), flush=True)
                    # Rewritten after every configuration: a long run stopped halfway keeps what it measured.
                    write_report(a, version, rows, runs, cmds)
    finally:
        if not a.work:
            shutil.rmtree(work, ignore_errors=True)
    return 0


def write_report(a, version, rows, runs, cmds):
    with open(a.out + ".json", "w", encoding="utf-8") as f:
        for r in runs:
            f.write(json.dumps(r) + "\n")
    lines = ["# sbarefine against colmap bundle_adjuster: shared-camera scenes", "",
             "Written by `bench/colmap_ba.py` (see bench/README.md) on %s UTC; %s; %d runs of each, the median "
             "wall time; peak RSS from /usr/bin/time -v; RMS reprojection error of the written model by one "
             "yardstick (tests/colmap_real/colmap_real.py). COLMAP uses every hardware thread (its "
             "bundle_adjuster has no threads option; %d here), sbarefine --threads %d. The machine is shared: "
             "each run's 1-minute load average is in colmap_ba.json."
             % (datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M"), version, a.repeat, os.cpu_count(), a.threads),
             "",
             "| images | observations | config | program | median wall s | all wall s | peak RSS MiB | iterations "
             "| RMS px (initial) | shared fx |",
             "|---:|---:|---|---|---:|---|---:|---:|---|---:|"]
    for r in rows:
        if r["exit"] == 0:
            lines.append("| %d | %d | %s | %s | %.2f | %s | %.0f | %s | %.6f (%.3f) | %.4f |" % (
                r["images"], r["observations"], r["config"], r["program"], r["median"],
                " ".join("%.2f" % w for w in r["walls"]), r["rss"], r["iterations"], r["rms"], r["rms0"], r["focal"]))
        else:
            lines.append("| %d | %d | %s | %s | exit %d | | | | %s | |" % (
                r["images"], r["observations"], r["config"], r["program"], r["exit"], r["why"].replace("|", "/")))
    lines += ["", "Commands (`$WORK` the scratch directory; each run writes into a fresh directory):", "", "```",
              " ".join(["bench/colmap_ba.py", "--sbagen", a.sbagen, "--sbarefine", a.sbarefine, "--sizes", a.sizes,
                        "--repeat", str(a.repeat), "--threads", str(a.threads), "--configs", a.configs,
                        "--points-per-image", str(a.points_per_image)])]
    lines += [c for c in cmds] + ["```", ""]
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
