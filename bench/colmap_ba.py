#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""sbarefine against `colmap bundle_adjuster` on scenes of sbagen with shared cameras.

Two kinds of scene (--scene), each converted to a binary model by `colmap model_converter` (the
input is one COLMAP wrote):
  fixed   sbagen --kind fixed: one PINHOLE camera for every image, its focal length started 2%
          long;
  opencv  sbagen --kind varKD: an OPENCV camera per image, then the cameras shared as --sharing
          says, each sharing a model of its own from the same observations:
            own       a camera per image (the same model unshared);
            pairs     images 2k and 2k+1 (in IMAGE_ID order) share the camera of image 2k;
            groups:N  images in consecutive groups of N share the camera of the group's first.
          So that a shared camera is the true model, every image sees through the lens of the
          first: each observation is moved by the difference between that lens's projection and
          its own image's of the true point from the true pose (sbagen's -truth files), its noise
          kept; each camera starts at sbagen's perturbed focal length and distortion, and its
          principal point (held by both programs' defaults) at the true one.
--trajectory is sbagen's (orbit or photo); --points its number of points (default
--points-per-image per image).

Two configurations, each program run --repeat times on the same input into a fresh directory
under /usr/bin/time -v (sbarefine once for each of --solvers):
  default  both programs at their defaults (each refines the focal lengths and the extra
           parameters, the poses and the points; principal points held);
  held     the intrinsics held by both (COLMAP --BundleAdjustment.refine_focal_length 0
           --BundleAdjustment.refine_extra_params 0, sbarefine --intrinsics none): the same
           problem for both.
Reported: the median of the wall times (and all of them, with the 1-minute load average when
each started), the largest peak RSS, the iterations, and the RMS reprojection error of the
written model measured by one yardstick for both (tests/colmap_real/colmap_real.py's projection
of COLMAP's camera models); then each row's time and peak RSS against the same images unshared,
and sbarefine's against COLMAP's. A run still going after --timeout seconds is killed and shown
as timed out (its peak RSS is up to then); the repeats of that row stop there. --skip leaves
out rows named PROGRAM@SHARING (colmap, or an sbarefine solver: colmap@own,chol@own), such as
runs known to time out.

Threads: COLMAP 3.8's bundle_adjuster has no option for them (Ceres gets every hardware
thread); sbarefine is given --threads THREADS (default 2, this machine's core count).

  bench/colmap_ba.py --sbagen build/demo/sbagen --sbarefine build/demo/sbarefine \\
      [--colmap colmap] [--sizes 100,300,1000] [--repeat 3] [--threads 2] [--configs default,held] \\
      [--scene fixed|opencv] [--sharing own,pairs,groups:N] [--trajectory orbit|photo] \\
      [--points-per-image 100 | --points N] [--solvers LIST] [--timeout SEC] \\
      [--skip colmap@own,...] [--out bench/results/colmap_ba] [--work DIR]
writes OUT.md (the tables and the exact commands) and OUT.json (one JSON object a run).
"""
import argparse
import datetime
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ left in the source tree by the import below
sys.path.insert(0, os.path.join(HERE, "..", "tests", "colmap_real"))
import colmap_real  # noqa: E402  (the yardstick and the model readers)


def timed(cmd, log, timeout=None, env=None):
    """Runs cmd under /usr/bin/time -v (in the environment env, None: this one): (exit status,
    wall seconds, peak RSS in MiB, output, whether it was killed at `timeout` seconds)."""
    t0 = time.monotonic()
    p = subprocess.Popen(["/usr/bin/time", "-v"] + cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         env=env)
    try:
        out, _ = p.communicate(timeout=timeout)
        killed = False
    except subprocess.TimeoutExpired:
        # Only the program is killed, not /usr/bin/time, which then reports its peak RSS so far.
        with open("/proc/%d/task/%d/children" % (p.pid, p.pid), encoding="ascii") as f:
            children = [int(pid) for pid in f.read().split()]
        for pid in children:
            os.kill(pid, signal.SIGKILL)
        out, _ = p.communicate()
        killed = bool(children)
    wall = time.monotonic() - t0
    with open(log, "w", encoding="utf-8") as f:
        f.write(" ".join(cmd) + "\n" + out)
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", out)
    st = re.search(r"Exit status: (\d+)", out)
    status = int(st.group(1)) if st else p.returncode
    return status, wall, int(m.group(1)) / 1024.0 if m else float("nan"), out, killed


def iterations(program, out):
    m = (re.search(r"SBA returned \S+ in (\d+) iter", out) if program == "sbarefine"
         else re.search(r"Iterations : (\d+)", out))
    return int(m.group(1)) if m else None


def refusal(out):
    """The program's own message, without /usr/bin/time's report."""
    lines = [ln for ln in out.splitlines() if ln.strip() and not ln.startswith("\t")
             and "Command exited with non-zero status" not in ln]
    return lines[-1] if lines else ""


def sharing_list(text):
    """--sharing: [(label, images per camera)] from own, pairs, groups:N."""
    out = []
    for item in text.split(","):
        m = re.fullmatch(r"groups:([1-9]\d*)", item)
        if item not in ("own", "pairs") and not m:
            raise argparse.ArgumentTypeError("%r is not own, pairs or groups:N (N >= 1)" % item)
        out.append((item, 1 if item == "own" else 2 if item == "pairs" else int(m.group(1))))
    return out


def numbers(path):
    """The rows of numbers of an sbagen file, its comment lines left out."""
    with open(path, encoding="utf-8") as f:
        return [[float(v) for v in ln.split()] for ln in f if ln.strip() and not ln.startswith("#")]


def one_lens(m, prefix):
    """Makes every image of an sbagen --kind varKD model see through the true lens of the
    first (see the opening comment). sbagen writes the images and the points in increasing
    identifiers in the order of its truth files' lines."""
    cams = numbers(prefix + "-truth-cams.txt")  # fu u0 v0 ar s kc0..kc4 q0..q3 t0..t2
    xyz = dict(zip(sorted(m.points), (row[:3] for row in numbers(prefix + "-truth-pts.txt"))))
    images = sorted(m.images)
    assert len(cams) == len(images) and len(xyz) == len(m.points), "sbagen's truth does not match its model"

    def lens(c):
        _, w, h, _ = m.cameras[m.images[images[0]]["camera_id"]]
        return ("OPENCV", w, h, [c[0], c[0] * c[3], c[1], c[2]] + c[5:9])

    first = lens(cams[0])
    for iid, c in zip(images, cams):
        im = m.images[iid]
        own, q, t = lens(c), c[10:14], c[14:17]
        for k, pid in enumerate(im["ids"]):
            if pid in xyz:
                x0, y0 = colmap_real.project(first, q, t, xyz[pid])
                x1, y1 = colmap_real.project(own, q, t, xyz[pid])
                im["xys"][k] = (im["xys"][k][0] + x0 - x1, im["xys"][k][1] + y0 - y1)
        name, w, h, p = m.cameras[im["camera_id"]]
        m.cameras[im["camera_id"]] = (name, w, h, p[:2] + first[3][2:4] + p[4:])


def share_cameras(m, size):
    """m with its images, in IMAGE_ID order, in consecutive groups of `size` that use the
    camera of the group's first image (the points and observations are m's own)."""
    s = colmap_real.Model()
    s.points = m.points
    images = sorted(m.images)
    for k, iid in enumerate(images):
        s.images[iid] = dict(m.images[iid], camera_id=m.images[images[k - k % size]]["camera_id"])
    for cid in {im["camera_id"] for im in s.images.values()}:
        s.cameras[cid] = m.cameras[cid]
    return s


def make_scene(a, n, work):
    """Writes the scene of n images: its directory, [(sharing, binary input model)] and the
    sbagen command."""
    d = os.path.join(work, "scene%d" % n)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    gen, prefix = os.path.join(d, "sbagen_text"), os.path.join(d, "gen")
    cmd = [a.sbagen, "--out", prefix, "--colmap", gen, "--kind", "fixed" if a.scene == "fixed" else "varKD",
           "--trajectory", a.trajectory, "--cameras", str(n), "--points", str(a.points or n * a.points_per_image),
           "--seed", "36", "--quiet"]
    subprocess.run(cmd, check=True)
    m = colmap_real.read_text_model(gen)
    if a.scene == "fixed":
        colmap_real.edit_shared(m)
        models = [("all", m)]
    else:
        one_lens(m, prefix)
        models = [(label, share_cameras(m, size)) for label, size in a.sharing]
    inputs = []
    for label, model in models:
        edited, inp = [os.path.join(d, "%s_%s" % (label.replace(":", ""), what)) for what in ("text", "input")]
        colmap_real.write_text_model(model, edited)
        os.makedirs(inp)
        subprocess.run([a.colmap, "model_converter", "--input_path", edited, "--output_path", inp,
                        "--output_type", "BIN"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        inputs.append((label, inp))
    return d, inputs, cmd


def commands(a, config, inp, out, solver):
    colmap = [a.colmap, "bundle_adjuster", "--input_path", inp, "--output_path", out]
    sba = [a.sbarefine, inp, "--write", out, "--threads", str(a.threads)] + (["--solver", solver] if solver else [])
    if config == "held":
        colmap += ["--BundleAdjustment.refine_focal_length", "0", "--BundleAdjustment.refine_extra_params", "0"]
        sba += ["--intrinsics", "none"]
    return {"colmap": colmap, "sbarefine": sba}


def measure(a, key, inp, outdir, runs, cmds, work):
    """Runs one row (key: images, observations, cameras, sharing, config, program, solver)
    --repeat times; appends its runs to `runs` and returns the row."""
    walls, rss, status, out, its, killed = [], [], 0, "", None, False
    for k in range(a.repeat):
        shutil.rmtree(outdir, ignore_errors=True)
        os.makedirs(outdir)
        cmd = commands(a, key["config"], inp, outdir, key["solver"])[key["program"]]
        load = os.getloadavg()[0]
        status, wall, peak, out, killed = timed(cmd, outdir + ".log%d" % k, a.timeout)
        its = None if killed else iterations(key["program"], out)
        if k == 0:
            cmds.append(" ".join(cmd).replace(work, "$WORK"))
        runs.append(dict(key, run=k, exit=status, timed_out=killed, wall_s=round(wall, 3), peak_rss_mib=round(peak, 1),
                         iterations=its, load_avg_1min=load, command=" ".join(cmd)))
        walls.append(wall)
        rss.append(peak)
        if status != 0 or killed:
            break
    row = dict(key, exit=status, timed_out=killed, walls=walls, loads=[r["load_avg_1min"] for r in runs[-len(walls):]],
               rss=max(rss))
    if killed:
        row["why"] = "timed out after %.0f s" % walls[-1]
    elif status != 0:
        row["why"] = refusal(out).replace(work, "$WORK")
    else:
        result = colmap_real.read_model(outdir)
        row.update(median=statistics.median(walls), iterations=its, rms=colmap_real.rms_error(result)[0],
                   focal=result.cameras[min(result.cameras)][3][0])
        runs[-1]["rms"] = row["rms"]
    return row


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sbagen", required=True)
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--colmap", default=shutil.which("colmap") or "/usr/bin/colmap")
    ap.add_argument("--sizes", default="100,300,1000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scene", choices=("fixed", "opencv"), default="fixed")
    ap.add_argument("--sharing", type=sharing_list, default="own", help="opencv: own, pairs, groups:N, comma-separated")
    ap.add_argument("--trajectory", choices=("orbit", "photo"), default="orbit")
    ap.add_argument("--points-per-image", type=int, default=100)
    ap.add_argument("--points", type=int, help="the scene's points (default: --points-per-image per image)")
    ap.add_argument("--solvers", default="", help="sbarefine --solver values, comma-separated, a row each "
                    "(default: its default solver)")
    ap.add_argument("--timeout", type=float, help="seconds after which a run is killed and shown as timed out")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "colmap_ba"))
    ap.add_argument("--configs", default="default,held", help="which configurations, comma-separated")
    ap.add_argument("--skip", default="", help="rows left out, PROGRAM@SHARING comma-separated: colmap@own,chol@own")
    ap.add_argument("--work", help="scenes and outputs here, kept (default: a temporary directory, removed)")
    a = ap.parse_args(argv)
    if a.scene == "fixed" and a.sharing != [("own", 1)]:
        ap.error("--sharing is for --scene opencv (a fixed scene has one camera)")
    if not os.access(a.colmap, os.X_OK):
        print("colmap_ba: no colmap program at %s" % a.colmap, file=sys.stderr)
        return 1
    work = a.work or tempfile.mkdtemp(prefix="colmap_ba.")
    os.makedirs(work, exist_ok=True)
    colmap_real.colmap_logs_into(work)
    version = subprocess.run([a.colmap, "-h"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True).stdout.strip().splitlines()[0]
    programs = [("colmap", None)] + [("sbarefine", s or None) for s in a.solvers.split(",")]
    runs, rows, cmds = [], [], []
    try:
        for n in [int(s) for s in a.sizes.split(",")]:
            d, inputs, gen_cmd = make_scene(a, n, work)
            cmds.append(" ".join(gen_cmd).replace(work, "$WORK") + "   # then " +
                        ("the focal length * 1.02" if a.scene == "fixed" else "one lens, cameras shared") +
                        ", colmap model_converter to BIN")
            for sharing, inp in inputs:
                scene = colmap_real.read_model(inp)
                rms0, nobs = colmap_real.rms_error(scene)
                print("colmap_ba: %d images, %d cameras (%s), %d points, %d observations, initial RMS %.4f px"
                      % (n, len(scene.cameras), sharing, len(scene.points), nobs, rms0), flush=True)
                for config in a.configs.split(","):
                    for program, solver in programs:
                        if "%s@%s" % (solver or program, sharing) in a.skip.split(","):
                            continue
                        key = {"images": n, "points": len(scene.points), "observations": nobs,
                               "cameras": len(scene.cameras), "sharing": sharing, "config": config,
                               "program": program, "solver": solver}
                        outdir = os.path.join(d, "%s_%s_%s%s" % (sharing.replace(":", ""), config, program,
                                                                 "_" + solver if solver else ""))
                        row = measure(a, key, inp, outdir, runs, cmds, work)
                        row["rms0"] = rms0
                        rows.append(row)
                        print("  %-8s %-25s %s" % (config, label(row), "median %.2f s, %.0f MiB, RMS %.6f px, %s iterations"
                                                   % (row["median"], row["rss"], row["rms"], row["iterations"])
                                                   if "why" not in row else "%s: %s" % (exit_text(row), row["why"])),
                              flush=True)
                        # Rewritten after every row: a long run stopped halfway keeps what it measured.
                        write_report(a, version, rows, runs, cmds)
    finally:
        if not a.work:
            shutil.rmtree(work, ignore_errors=True)
    return 0


def label(r):
    return r["program"] + (" " + r["solver"] if r["solver"] else "")


def exit_text(r):
    return "timed out" if r["timed_out"] else "exit %d" % r["exit"]


def ratio(r, base, field):
    """r's median time (field "median") or peak RSS ("rss") over base's, as text: a bound when
    one of them timed out, empty when one failed."""
    if (r["exit"] != 0 and not r["timed_out"]) or (base["exit"] != 0 and not base["timed_out"]):
        return ""
    if field == "rss":
        return "%.2f" % (r["rss"] / base["rss"]) if not (r["timed_out"] or base["timed_out"]) else ""
    if r["timed_out"] and base["timed_out"]:
        return ""
    x = (r["walls"][-1] if r["timed_out"] else r["median"]) / (base["walls"][-1] if base["timed_out"] else base["median"])
    return ("> %.2f" if r["timed_out"] else "< %.2f" if base["timed_out"] else "%.2f") % x


def ratio_lines(rows):
    """The table of each row against the same images unshared (same configuration, program and
    solver) and of each sbarefine row against COLMAP on the same model."""
    def find(r, **changes):
        want = dict({k: r[k] for k in ("images", "sharing", "config", "program", "solver")}, **changes)
        return next((b for b in rows if all(b[k] == v for k, v in want.items())), None)

    lines = []
    for r in rows:
        own = find(r, sharing="own") if r["sharing"] not in ("own", "all") else None
        colmap = find(r, program="colmap", solver=None) if r["program"] == "sbarefine" else None
        if not own and not colmap:
            continue
        rms = ("%.6f / %.6f" % (r["rms"], colmap["rms"]) if colmap and "rms" in r and "rms" in colmap else "")
        lines.append("| %d | %d (%s) | %s | %s | %s | %s | %s | %s | %s |" % (
            r["images"], r["cameras"], r["sharing"], r["config"], label(r), ratio(r, own, "median") if own else "",
            ratio(r, own, "rss") if own else "", ratio(r, colmap, "median") if colmap else "",
            ratio(r, colmap, "rss") if colmap else "", rms))
    if not lines:
        return []
    return ["", "Ratios of the medians (time) and of the peak RSS: against the same images with a camera per image "
            "(`own`; same configuration, program and solver), and sbarefine against COLMAP on the same model, with "
            "both RMS errors (a bound where a run timed out):", "",
            "| images | cameras | config | program | time / own | peak RSS / own | time / COLMAP | peak RSS / COLMAP "
            "| RMS px sbarefine / COLMAP |", "|---:|---|---|---|---:|---:|---:|---:|---|"] + lines


def write_report(a, version, rows, runs, cmds):
    with open(a.out + ".json", "w", encoding="utf-8") as f:
        for r in runs:
            f.write(json.dumps(r) + "\n")
    scene = ("sbagen --kind fixed, one PINHOLE camera" if a.scene == "fixed" else
             "sbagen --kind varKD, OPENCV cameras, shared as the cameras column says (one lens for all images)")
    lines = ["# sbarefine against colmap bundle_adjuster: shared-camera scenes", "",
             "Written by `bench/colmap_ba.py` (see bench/README.md) on %s UTC; %s; %s, trajectory %s; %d runs of each, "
             "the median wall time; peak RSS from /usr/bin/time -v; RMS reprojection error of the written model by one "
             "yardstick (tests/colmap_real/colmap_real.py). COLMAP uses every hardware thread (its "
             "bundle_adjuster has no threads option; %d here), sbarefine --threads %d.%s The machine is shared: "
             "the load column is each run's 1-minute load average when it started."
             % (datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M"), version, scene, a.trajectory, a.repeat,
                os.cpu_count(), a.threads, " A run is killed after %.0f s." % a.timeout if a.timeout else ""),
             "",
             "| images | observations | cameras | config | program | median wall s | all wall s | load | peak RSS MiB "
             "| iterations | RMS px (initial) | fx of the first camera |",
             "|---:|---:|---|---|---|---:|---|---|---:|---:|---|---:|"]
    for r in rows:
        common = "| %d | %d | %d (%s) | %s | %s |" % (r["images"], r["observations"], r["cameras"], r["sharing"],
                                                   r["config"], label(r))
        walls = " ".join("%.2f" % w for w in r["walls"])
        loads = " ".join("%.1f" % x for x in r["loads"])
        if "why" not in r:
            lines.append(common + " %.2f | %s | %s | %.0f | %s | %.6f (%.3f) | %.4f |" % (
                r["median"], walls, loads, r["rss"], r["iterations"], r["rms"], r["rms0"], r["focal"]))
        else:
            lines.append(common + " %s | %s | %s | %s | | %s (%.3f) | |" % (
                exit_text(r), walls, loads, "%.0f" % r["rss"] if r["timed_out"] else "",
                r["why"].replace("|", "/"), r["rms0"]))
    lines += ratio_lines(rows)
    lines += ["", "Commands (`$WORK` the scratch directory; each run writes into a fresh directory):", "", "```",
              " ".join(["bench/colmap_ba.py", "--sbagen", a.sbagen, "--sbarefine", a.sbarefine, "--sizes", a.sizes,
                        "--repeat", str(a.repeat), "--threads", str(a.threads), "--configs", a.configs,
                        "--scene", a.scene, "--trajectory", a.trajectory] +
                       (["--sharing", ",".join(s for s, _ in a.sharing)] if a.scene == "opencv" else []) +
                       (["--points", str(a.points)] if a.points else ["--points-per-image", str(a.points_per_image)]) +
                       (["--solvers", a.solvers] if a.solvers else []) +
                       (["--timeout", "%g" % a.timeout] if a.timeout else []) +
                       (["--skip", a.skip] if a.skip else []))]
    lines += [c for c in cmds] + ["```", ""]
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
