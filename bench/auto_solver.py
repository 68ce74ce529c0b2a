#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Every linear solver that fits, and `auto`, on the photo-collection series: sbarefine on COLMAP
models of sbagen's photo, orbit and path scenes.

Scenes (100 points per image, sbagen's other options at their defaults, seed 36; each written
by sbagen as a COLMAP text model and converted to a binary one by `colmap model_converter`
when COLMAP is installed):
  shared  sbagen --kind fixed: one PINHOLE camera for every image, its focal length started
          2% long (tests/colmap_real/colmap_real.py's edit_shared, as bench/colmap_ba.py);
  own     sbagen --kind varKD: an OPENCV camera per image.
sbarefine runs at its defaults (COLMAP's: focal length and extra parameters refined, the
principal point held, trust-region LM, at most 100 iterations) under /usr/bin/time -v, once
per solver of --solvers: `auto` is sbarefine without --solver (its default), the others with
--solver NAME. Recorded per run: the wall time and the solve's own time (sbarefine --json
"seconds"), the peak RSS, the iterations, the final RMS reprojection error, the solver that
ran, and the 1-minute load average when it started. Runs under --repeat-below seconds are
repeated, --repeat times in all, in rounds over the solvers (each round runs each solver once,
so that a spell of load from other work falls on all alike); the run of the median solve time
stands for a solver (all are recorded).

What is not run, and said so in the table (with --once-from, also the solver auto chose, from
that many images on: auto's run is that solver's, bit for bit, so it runs once):
  - a solver whose memory could exceed --mem-limit GiB: chol's dense S (8 N^2 bytes for N
    camera unknowns), sparse-chol's S and factor where S is dense (photo, orbit: 12 N^2);
  - a solver that timed out at the previous size of the same scene, or whose time there,
    times the growth of an N^2 cost to this size, exceeds --timeout.
A run still going after --timeout seconds is killed and shown as timed out.

  bench/auto_solver.py --sbagen build/demo/sbagen --sbarefine build/demo/sbarefine \\
      [--sizes 50,100,300,1000] [--trajectories photo,orbit,path] [--cameras shared,own] \\
      [--solvers chol,sparse-chol,iterative-schur,auto] [--timeout 900] [--mem-limit 12] \\
      [--repeat 3 --repeat-below 30] [--once-from 3000] \\
      [--work DIR] [--out bench/results/auto_solver]
appends its runs to OUT.json (JSON lines; a run of the same scene, size and solver replaces the
older one) and rewrites OUT.md from all of them.
"""
import argparse
import datetime
import json
import math
import os
import re
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ left in the source tree by the import below
sys.path.insert(0, os.path.join(HERE, "..", "tests", "colmap_real"))
import colmap_real  # noqa: E402  (the model reader and writer, and edit_shared)
import colmap_ba  # noqa: E402  (timed: a run under /usr/bin/time -v, killed at a timeout)

SEED = 36
POINTS_PER_IMAGE = 100
# Camera unknowns per image in sbarefine's layout: the pose, and with a camera per image its
# OPENCV slots (the held principal point included); a shared PINHOLE camera adds 2 in all.
UNKNOWNS_PER_IMAGE = {"shared": 6, "own": 16}


def make_scene(a, trajectory, cameras, n, work):
    """The binary (or, without COLMAP, text) model of one scene, made once into `work` and
    kept there; returns its directory and the commands that made it."""
    d = os.path.join(work, "%s_%s_%d" % (trajectory, cameras, n))
    model = os.path.join(d, "input")
    gen = [a.sbagen, "--out", os.path.join(d, "gen"), "--colmap", os.path.join(d, "text"), "--kind",
           "fixed" if cameras == "shared" else "varKD", "--trajectory", trajectory, "--cameras", str(n),
           "--points", str(n * POINTS_PER_IMAGE), "--seed", str(SEED), "--quiet"]
    steps = [" ".join(gen)]
    if cameras == "shared":
        steps.append("the focal length * 1.02")
    colmap = a.colmap if a.colmap and os.access(a.colmap, os.X_OK) else None
    if colmap:
        steps.append("colmap model_converter to BIN")
    if os.path.isdir(model):
        return model, steps
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    subprocess.run(gen, check=True)
    text = os.path.join(d, "text")
    if cameras == "shared":
        m = colmap_real.read_text_model(text)
        colmap_real.edit_shared(m)
        text = os.path.join(d, "edited")
        colmap_real.write_text_model(m, text)
    tmp = model + ".tmp"
    os.makedirs(tmp)
    if colmap:
        subprocess.run([colmap, "model_converter", "--input_path", text, "--output_path", tmp, "--output_type", "BIN"],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    else:
        for f in os.listdir(text):
            shutil.copy(os.path.join(text, f), tmp)
    os.rename(tmp, model)
    return model, steps


def skip_reason(a, key, unknowns, runs):
    """Why a run is not started (memory, time, or the same run as auto's), or None."""
    gib = 1024.0 ** 3
    solver = key["solver"]
    if a.once_from and key["images"] >= a.once_from:
        auto = [r for r in runs if all(r[k] == key[k] for k in ("trajectory", "cameras", "images"))
                and r["solver"] == "auto" and r.get("solver_ran") == solver]
        if auto:
            return "auto ran it (the same solve, bit for bit)"
    if solver == "chol" and 8.0 * unknowns ** 2 > a.mem_limit * gib:
        return "dense S of %d unknowns: %.0f GiB" % (unknowns, 8.0 * unknowns ** 2 / gib)
    if solver == "sparse-chol" and key["trajectory"] != "path" and 12.0 * unknowns ** 2 > a.mem_limit * gib:
        return "S dense, %d unknowns: S and factor about %.0f GiB" % (unknowns, 12.0 * unknowns ** 2 / gib)
    smaller = [r for r in runs if all(r[k] == key[k] for k in ("trajectory", "cameras", "solver"))
               and r["images"] < key["images"]]
    if not smaller:
        return None
    prev = max(smaller, key=lambda r: r["images"])
    if prev.get("timed_out"):
        return "timed out at %d images" % prev["images"]
    if prev.get("skipped"):
        return "not run at %d images" % prev["images"]
    if prev.get("wall_s") is not None:
        # A dense factorization's time grows at least as the square of the images here; the
        # others' about linearly (sparse-chol on the banded S of a path).
        power = 2 if solver == "chol" or (solver == "sparse-chol" and key["trajectory"] != "path") else 1
        predicted = prev["wall_s"] * (key["images"] / prev["images"]) ** power
        if predicted > a.timeout:
            return "%.0f s at %d images predicts %.0f s" % (prev["wall_s"], prev["images"], predicted)
    return None


def attempt(a, cmd, out):
    """One run of cmd: what /usr/bin/time and sbarefine's --json say of it."""
    if os.path.exists(out + ".json"):
        os.remove(out + ".json")
    load = os.getloadavg()[0]
    status, wall, rss, text, killed = colmap_ba.timed(cmd, out + ".log", a.timeout)
    rss = None if math.isnan(rss) else rss
    t = dict(load_avg_1min=round(load, 2), exit=status, timed_out=killed, wall_s=round(wall, 3),
             peak_rss_mib=round(rss, 1) if rss is not None else None)
    m = re.search(r"SBA returned \S+ in (\d+) iter", text)
    t["iterations"] = int(m.group(1)) if m else None
    if not killed and status == 0 and os.path.exists(out + ".json"):
        with open(out + ".json", encoding="utf-8") as f:
            report = json.load(f)
        t.update(solve_s=report["seconds"], rms_px=report["rms_px"]["final"], rms0_px=report["rms_px"]["initial"],
                 solver_ran=report["solver"], observations=report["sizes"]["observations"],
                 stop_reason=report["stop_reason"])
    elif not killed:
        t["why"] = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("\t")][-1:]
    return t


def finished(row, tries):
    """The row of a solver from its tries: the one of the median solve time stands for them."""
    done = sorted((t for t in tries if "solve_s" in t), key=lambda t: t["solve_s"])
    row = dict(row)
    row.update(done[(len(done) - 1) // 2] if len(done) == len(tries) else tries[-1])
    row.update(solve_s_all=[t.get("solve_s") for t in tries], wall_s_all=[t["wall_s"] for t in tries],
               load_avg_1min_all=[t["load_avg_1min"] for t in tries])
    return row


def run_scene(a, scene, model, unknowns, scene_command, runs, record):
    """Every solver on one scene, in rounds: each round runs each solver once, so that a spell
    of load from other work falls on all of them alike. A solver that failed, timed out or took
    --repeat-below seconds or more runs once. record(row) keeps each row as it changes."""
    t, c, n = scene
    solvers = a.solvers.split(",")
    if a.once_from and n >= a.once_from and "auto" in solvers:
        solvers = ["auto"] + [x for x in solvers if x != "auto"]
    base, tries = {}, {}
    for k in range(a.repeat):
        for s in solvers:
            key = {"trajectory": t, "cameras": c, "images": n, "solver": s}
            out = os.path.join(a.work, "runs", "%s_%s_%d_%s" % (t, c, n, s))
            os.makedirs(os.path.dirname(out), exist_ok=True)
            cmd = [a.sbarefine, model, "--json", out + ".json", "--no-progress"] + ([] if s == "auto" else ["--solver", s])
            if k == 0:
                base[s] = dict(key, unknowns=unknowns, command=" ".join(cmd).replace(a.work, "$WORK"),
                               scene_command=scene_command, invocation=" ".join(["bench/auto_solver.py"] + a.argv_text))
                why = skip_reason(a, key, unknowns, runs())
                if why:
                    record(dict(base[s], skipped=why))
                    continue
                tries[s] = []
            elif s not in tries or "solve_s" not in tries[s][-1] or tries[s][-1]["wall_s"] >= a.repeat_below:
                continue
            tries[s].append(attempt(a, cmd, out))
            record(finished(base[s], tries[s]))


def load_runs(path):
    if not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as f:
        return [json.loads(ln) for ln in f if ln.strip()]


def key_of(r):
    return (r["trajectory"], r["cameras"], r["images"], r["solver"])


def cell(r):
    if r is None:
        return ""
    if r.get("skipped"):
        return "not run: " + r["skipped"]
    if r.get("timed_out"):
        return "timed out after %.0f s (%s MiB)" % (r["wall_s"], "%.0f" % r["peak_rss_mib"] if r["peak_rss_mib"] else "?")
    if "solve_s" not in r:
        return "failed (exit %s)" % r.get("exit")
    return "%.2f s / %.0f MiB / %d it / %.6f px" % (r["solve_s"], r["peak_rss_mib"], r["iterations"], r["rms_px"])


def write_report(a, runs):
    solvers = ["chol", "sparse-chol", "iterative-schur"]
    lines = ["# The linear solver `auto` against every solver that fits: sbarefine on sbagen's scenes", "",
             "Written by `bench/auto_solver.py` (see its opening comment and docs/solvers.md) on %s UTC, %d hardware "
             "threads, sbarefine at its defaults but for `--solver` (`auto` is no `--solver`). A cell: the solve's "
             "time (sbarefine's own, reading and writing excluded) / peak RSS of the whole run / iterations / final "
             "RMS reprojection error. `auto / fastest`: auto's solve time over the fastest solver's that reached the "
             "same RMS (to 1e-6 relative); `chosen / fastest`: the same for the run of the solver auto chose, "
             "named (auto's run is that solver's, bit for bit: where the two ratios differ, the difference is the "
             "machine's noise). Wall times, loads and the commands are in auto_solver.json. The machine is "
             "shared: each run's 1-minute load average when it started is in the load column (min-max over the row)."
             % (datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M"), os.cpu_count()), ""]
    lines += ["| scene | cameras | images | observations | camera unknowns | " + " | ".join(solvers) +
              " | auto | auto chose | auto / fastest | chosen / fastest | load |",
              "|---|---|---:|---:|---:|" + "---|" * len(solvers) + "---|---|---:|---:|---|"]
    by_key = {key_of(r): r for r in runs}
    scenes = sorted({(r["trajectory"], r["cameras"], r["images"]) for r in runs},
                    key=lambda s: (["photo", "orbit", "path"].index(s[0]), s[1] != "shared", s[2]))
    for t, c, n in scenes:
        rows = {s: by_key.get((t, c, n, s)) for s in solvers + ["auto"]}
        done = [r for r in rows.values() if r and "solve_s" in r]
        nobs = done[0]["observations"] if done else ""
        unknowns = next((r["unknowns"] for r in rows.values() if r), "")
        auto = rows["auto"]
        ratio = chosen = ""
        if auto and "solve_s" in auto:
            same = [r for s, r in rows.items() if s != "auto" and r and "solve_s" in r
                    and abs(r["rms_px"] - auto["rms_px"]) <= 1e-6 * auto["rms_px"]]
            if same:
                fastest = min(r["solve_s"] for r in same)
                ratio = "%.2f" % (auto["solve_s"] / fastest)
                picked = rows.get(auto.get("solver_ran"))
                if picked and "solve_s" in picked:
                    chosen = "%.2f" % (picked["solve_s"] / fastest)
        loads = [r["load_avg_1min"] for r in rows.values() if r and "load_avg_1min" in r]
        lines.append("| %s | %s | %d | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            t, c, n, nobs, unknowns, " | ".join(cell(rows[s]) for s in solvers), cell(auto),
            auto.get("solver_ran", "") if auto else "", ratio, chosen,
            "%.1f-%.1f" % (min(loads), max(loads)) if loads else ""))
    distinct = lambda field: list(dict.fromkeys(r[field] for r in runs if field in r))  # noqa: E731
    lines += ["", "Commands (`$WORK` the scratch directory): the invocations, then the scenes they made, then the "
              "runs of the largest size (the others differ only in the scene's name):", "", "```"]
    lines += distinct("invocation") + distinct("scene_command")
    largest = max(r["images"] for r in runs)
    lines += [r["command"] for r in runs if r["images"] == largest]
    lines += ["```", ""]
    with open(a.out + ".md", "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sbagen", required=True)
    ap.add_argument("--sbarefine", required=True)
    ap.add_argument("--colmap", default=shutil.which("colmap") or "/usr/bin/colmap")
    ap.add_argument("--sizes", default="50,100,300,1000")
    ap.add_argument("--trajectories", default="photo,orbit,path")
    ap.add_argument("--cameras", default="shared,own")
    ap.add_argument("--solvers", default="chol,sparse-chol,iterative-schur,auto")
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--repeat", type=int, default=3, help="runs of a configuration that takes under --repeat-below s")
    ap.add_argument("--repeat-below", type=float, default=30)
    ap.add_argument("--mem-limit", type=float, default=12, help="GiB a solver's predicted memory may take")
    ap.add_argument("--once-from", type=int, default=0,
                    help="from this many images on, the solver auto chose is not run again by name (auto first)")
    ap.add_argument("--work", default=os.path.join("/tmp", "auto_solver"))
    ap.add_argument("--out", default=os.path.join(HERE, "results", "auto_solver"))
    ap.add_argument("--report-only", action="store_true", help="rewrite OUT.md from OUT.json and stop")
    a = ap.parse_args(argv)
    a.argv_text = [x if not x.startswith(a.work) else x.replace(a.work, "$WORK") for x in argv]
    runs = load_runs(a.out + ".json")
    if a.report_only:
        write_report(a, runs)
        return 0
    os.makedirs(a.work, exist_ok=True)
    colmap_real.colmap_logs_into(a.work)
    for n in [int(s) for s in a.sizes.split(",")]:
        for t in a.trajectories.split(","):
            for c in a.cameras.split(","):
                model, steps = make_scene(a, t, c, n, a.work)
                scene_command = "   # then ".join(steps).replace(a.work, "$WORK")
                unknowns = UNKNOWNS_PER_IMAGE[c] * n + (2 if c == "shared" else 0)

                def record(row):
                    nonlocal runs
                    runs = [r for r in runs if key_of(r) != key_of(row)] + [row]
                    print("%-6s %-6s %5d %-15s %s" % (row["trajectory"], row["cameras"], row["images"], row["solver"],
                                                      cell(row)), flush=True)
                    # Rewritten after every run: a long series stopped halfway keeps what it measured.
                    with open(a.out + ".json", "w", encoding="utf-8") as f:
                        for r in runs:
                            f.write(json.dumps(r) + "\n")
                    write_report(a, runs)

                run_scene(a, (t, c, n), model, unknowns, scene_command, lambda: runs, record)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
