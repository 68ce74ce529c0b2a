# SPDX-License-Identifier: BSD-3-Clause
"""pysba's COLMAP models: read and written as the C++ reader and writer do (the files sbarefine
writes), refined as sbarefine refines them (the same bits), and refused with the reader's
messages. Models come from sbagen (PYSBA_SBAGEN), sbarefine is PYSBA_SBAREFINE; ctest sets
both. The conversions to and from pycolmap are tests/python/pycolmap_refine.py's."""
import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import pysba


def program(var):
    exe = os.environ.get(var)
    if not exe:
        pytest.skip(f"{var} is not set (ctest sets it)")
    return exe


def sbagen(out, kind="varKD", *args):
    """A COLMAP model of 6 images and 60 points, text (out/t) and binary (out/b)."""
    out.mkdir(exist_ok=True)
    subprocess.run([program("PYSBA_SBAGEN"), "--cameras", "6", "--points", "60", "--quiet", "--kind", kind,
                    "--out", str(out / "g"), "--colmap", str(out / "t"), "--colmap-binary", str(out / "b"),
                    *args], check=True)
    return out / "t", out / "b"


def files(d):
    return {name: (d / name).read_bytes() for name in sorted(os.listdir(d))}


def rad(a):
    """The unit quaternion of a rotation by a about x, 17 digits a value."""
    return [math.cos(a / 2), math.sin(a / 2), 0.0, 0.0]


def rigged(tmp_path):
    """sbagen's varKD text model with rigs and frames added, every kind of field the files have:
    rig 1 of camera 100 (its reference), camera 101 (posed in the rig) and an IMU without a
    pose; one rig for each other camera; a rig of no sensor; one frame per image (ids that are
    not image ids; the IMU's measurement in image 10's frame) and a frame of no measurement."""
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    q = " ".join(repr(v) for v in rad(0.01) + [0.01, 0.0, 0.0])
    rigs = ["# Rig list", f"1 3 CAMERA 100 CAMERA 101 1 {q} IMU 7 0"]
    rigs += [f"{k} 1 CAMERA {100 + k - 1}" for k in range(3, 7)] + ["9 0"]
    frames = ["# Frame list"]
    for j, im in enumerate(model.images):
        rig = 1 if j < 2 else j + 1
        pose = " ".join(repr(float(v)) for v in list(im.q) + list(im.t))
        data = f"2 CAMERA {im.camera_id} {im.id} IMU 7 55" if j == 0 else f"1 CAMERA {im.camera_id} {im.id}"
        frames.append(f"{900 + j} {rig} {pose} {data}")
    frames.append("999 9 1 0 0 0 0 0 0 0")
    (text / "rigs.txt").write_text("\n".join(rigs) + "\n")
    (text / "frames.txt").write_text("\n".join(frames) + "\n")
    return text


def same_array(a, b, what):
    assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray), what
    assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), what


def same_pose(a, b, what):
    if a.q is None or b.q is None:
        assert a.q is None and b.q is None and a.t is None and b.t is None, what
        return
    same_array(a.q, b.q, what + ".q")
    same_array(a.t, b.t, what + ".t")


def same_model(a, b):
    """Every field of a and b, the same bits."""
    assert [(c.id, c.model, c.width, c.height) for c in a.cameras] == \
        [(c.id, c.model, c.width, c.height) for c in b.cameras]
    for k, (c, d) in enumerate(zip(a.cameras, b.cameras)):
        same_array(c.params, d.params, f"cameras[{k}].params")
    assert [(i.id, i.name, i.camera_id) for i in a.images] == [(i.id, i.name, i.camera_id) for i in b.images]
    for k, (i, j) in enumerate(zip(a.images, b.images)):
        same_pose(i, j, f"images[{k}]")
        same_array(i.points2D, j.points2D, f"images[{k}].points2D")
        same_array(i.point3D_ids, j.point3D_ids, f"images[{k}].point3D_ids")
    for name in ("ids", "xyz", "rgb", "error", "track_offsets", "track_image_ids", "track_point2D_idxs"):
        same_array(getattr(a.points3D, name), getattr(b.points3D, name), f"points3D.{name}")
    assert (a.rigs is None) == (b.rigs is None) and (a.frames is None) == (b.frames is None)
    if a.rigs is None:
        return
    assert [(r.id, [(s.type, s.id) for s in r.sensors]) for r in a.rigs] == \
        [(r.id, [(s.type, s.id) for s in r.sensors]) for r in b.rigs]
    for k, (r, s) in enumerate(zip(a.rigs, b.rigs)):
        for i, (x, y) in enumerate(zip(r.sensors, s.sensors)):
            same_pose(x, y, f"rigs[{k}].sensors[{i}]")
    assert [(f.id, f.rig_id, list(f.data)) for f in a.frames] == \
        [(f.id, f.rig_id, list(f.data)) for f in b.frames]
    for k, (f, g) in enumerate(zip(a.frames, b.frames)):
        same_pose(f, g, f"frames[{k}]")


# ---- reading and writing ----

def test_read_gives_every_field(tmp_path):
    model = pysba.read_colmap(rigged(tmp_path))
    assert repr(model) == "ColmapModel(cameras=6, images=6, points3D=60, rigs=6, frames=7)"
    c = model.cameras[0]
    assert (c.id, c.model, c.width, c.height, c.params.shape) == (100, "OPENCV", 640, 480, (8,))
    im = model.images[0]
    assert (im.id, im.name, im.camera_id) == (10, "img_0000.png", 100)
    # sbagen's first keypoint of every image observes no point.
    assert im.point3D_ids.dtype == np.uint64 and im.point3D_ids[0] == pysba.NO_POINT3D
    assert im.points2D[0].tolist() == [0.5, 0.5]
    assert im.point3D_ids[1] == 1007 and model.points3D.ids[1] == 1007
    pts = model.points3D
    assert len(pts) == 60 and pts.ids.dtype == np.uint64 and pts.rgb.dtype == np.uint8
    assert pts.track_offsets[0] == 0 and pts.track_offsets[-1] == len(pts.track_image_ids)
    images, idxs = pts.track(1)  # point 1007, seen by image 10's keypoint 1, and others
    assert images[0] == 10 and idxs[0] == 1
    rig = model.rigs[0]
    assert [(s.type, s.id, s.q is None) for s in rig.sensors] == \
        [("CAMERA", 100, True), ("CAMERA", 101, False), ("IMU", 7, True)]
    assert rig.sensors[1].q.tolist() == rad(0.01) and rig.sensors[1].t.tolist() == [0.01, 0.0, 0.0]
    assert model.rigs[-1].id == 9 and model.rigs[-1].sensors == []
    assert model.frames[0].data == [("CAMERA", 100, 10), ("IMU", 7, 55)]
    assert (model.frames[-1].id, model.frames[-1].data) == (999, [])
    # Image 13's pose is composed from its frame's in rig 1 (COLMAP 4), not read from images.txt.
    plain = pysba.read_colmap(sbagen(tmp_path / "plain")[0])
    assert model.frames[1].q.tolist() == plain.images[1].q.tolist()
    assert not np.allclose(model.images[1].t, plain.images[1].t)


@pytest.mark.parametrize("encoding", ["text", "binary"])
def test_a_rewrite_is_the_same_files(tmp_path, encoding):
    text, binary = sbagen(tmp_path)
    source = text if encoding == "text" else binary
    pysba.write_colmap(pysba.read_colmap(source), tmp_path / "out", encoding)
    assert files(tmp_path / "out") == files(source)


@pytest.mark.parametrize("encoding", ["text", "binary"])
def test_round_trip_with_rigs_keeps_every_field(tmp_path, encoding):
    model = pysba.read_colmap(rigged(tmp_path))
    pysba.write_colmap(model, tmp_path / "a", encoding)
    back = pysba.read_colmap(tmp_path / "a")
    same_model(model, back)
    pysba.write_colmap(back, tmp_path / "b", encoding)
    extension = ".txt" if encoding == "text" else ".bin"
    names = [n + extension for n in ("cameras", "frames", "images", "points3D", "rigs")]
    assert sorted(os.listdir(tmp_path / "a")) == names
    assert files(tmp_path / "a") == files(tmp_path / "b")


@pytest.mark.parametrize("encoding", ["text", "binary"])
def test_written_as_sbarefine_converts(tmp_path, encoding):
    # sbarefine --itmax 0 writes the model as read, converted to --write-format.
    source = rigged(tmp_path)
    sb = tmp_path / "sbarefine"
    subprocess.run([program("PYSBA_SBAREFINE"), str(source), "--itmax", "0", "--write", str(sb),
                    "--write-format", encoding], check=True, capture_output=True)
    pysba.write_colmap(pysba.read_colmap(source), tmp_path / "pysba", encoding)
    assert files(tmp_path / "pysba") == files(sb)


def test_write_leaves_one_model(tmp_path):
    out = tmp_path / "out"
    pysba.write_colmap(pysba.read_colmap(rigged(tmp_path)), out, "text")
    plain = pysba.read_colmap(tmp_path / "b")
    assert plain.rigs is None
    pysba.write_colmap(plain, out, "binary")
    # The text model went, and no rigs and frames are left for COLMAP to pose the images by.
    assert sorted(os.listdir(out)) == ["cameras.bin", "images.bin", "points3D.bin"]
    same_model(pysba.read_colmap(out), plain)


def test_a_model_made_in_python(tmp_path):
    # Two images of one SIMPLE_PINHOLE camera seeing one point; -1 stands for NO_POINT3D; lists
    # and ints of any kind are taken.
    pts = pysba.ColmapPoints3D(ids=np.array([5]), xyz=[[0.0, 0.0, 5.0]], rgb=[[1, 2, 3]], error=[0.0],
                               track_offsets=[0, 2], track_image_ids=[1, 2], track_point2D_idxs=[0, 1])
    images = [pysba.ColmapImage(1, "a b.png", 1, [1, 0, 0, 0], [0, 0, 0], [[50, 50]], [5]),
              pysba.ColmapImage(2, "b.png", 1, [1, 0, 0, 0], [1, 0, 0], [[0, 0], [30, 50]],
                                np.array([-1, 5]))]
    camera = pysba.ColmapCamera(1, "SIMPLE_PINHOLE", 100, 100, [100.0, 50, 50])
    model = pysba.ColmapModel([camera], images, pts)
    pysba.write_colmap(model, tmp_path / "m", "text")
    back = pysba.read_colmap(tmp_path / "m")
    assert back.images[0].name == "a b.png" and back.images[1].point3D_ids.tolist() == [pysba.NO_POINT3D, 5]
    assert back.images[1].points2D.tolist() == [[0, 0], [30, 50]]
    assert back.points3D.rgb.tolist() == [[1, 2, 3]]
    cameras = (tmp_path / "m" / "cameras.txt").read_text().splitlines()
    assert cameras[-1] == "1 SIMPLE_PINHOLE 100 100 100 50 50"


def test_names_that_are_not_utf8_come_back(tmp_path):
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    model.images[0].name = os.fsdecode(b"caf\xe9.png")  # Latin-1: a lone surrogate in Python
    pysba.write_colmap(model, tmp_path / "out", "binary")
    assert b"caf\xe9.png\0" in (tmp_path / "out" / "images.bin").read_bytes()
    assert pysba.read_colmap(tmp_path / "out").images[0].name == model.images[0].name


# ---- refining: sbarefine's numbers ----

def sbarefine(model, out, args):
    cmd = [program("PYSBA_SBAREFINE"), str(model), "--write", str(out), "--json", str(out) + ".json",
           "--no-progress", *map(str, args)]
    subprocess.run(cmd, check=True, capture_output=True)
    with open(str(out) + ".json") as f:
        return json.load(f)


def same_as_sbarefine(tmp_path, model_dir, encoding, args, kw):
    # refine_colmap's gauge is its config's (None, as in COLMAP's BundleAdjustmentConfig: free);
    # sbarefine holds it as COLMAP's bundle adjuster does unless told: both are given the same.
    args = list(args) + ["--gauge", kw.get("gauge") or "none"]
    report = sbarefine(model_dir, tmp_path / "sbarefine", args)
    model = pysba.read_colmap(model_dir)
    refined, result = pysba.refine_colmap(model, **kw)
    pysba.write_colmap(refined, tmp_path / "pysba", encoding)
    assert files(tmp_path / "pysba") == files(tmp_path / "sbarefine")
    info = report["info"]
    assert result.info.tolist() == [info[k] for k in ("initial_error", "final_error", "gradient_inf_norm",
                                                      "step_norm_sq", "mu_ratio", "iterations", "stop_reason",
                                                      "function_evals", "jacobian_evals", "linear_systems")]
    assert (result.rms_initial, result.rms_final) == (report["rms_px"]["initial"], report["rms_px"]["final"])
    assert (result.sq_error_initial, result.sq_error_final) == (report["squared_error"]["initial"],
                                                                report["squared_error"]["final"])
    assert (result.solver, result.strategy) == (report["solver"], report["strategy"])
    assert result.model is refined
    # The input is left as it was.
    same_model(model, pysba.read_colmap(model_dir))
    return result


def test_refine_at_colmaps_defaults_is_sbarefines(tmp_path):
    text, _ = sbagen(tmp_path)
    r = same_as_sbarefine(tmp_path, text, "text", [], {})
    # COLMAP's defaults: the trust-region strategy until the cost stops changing.
    assert r.strategy == "trust-region" and r.iterations >= 3 and r.rms_final < 0.6 < 16 < r.rms_initial


def test_refine_with_options_is_sbarefines(tmp_path):
    # One PINHOLE camera shared by every image (refined once), binary, other options.
    _, binary = sbagen(tmp_path, "fixed")
    same_as_sbarefine(tmp_path, binary, "binary",
                      ["--refine-principal-point", "1", "--refine-extra-params", "0", "--hold-poses",
                       "13,img_0004.png", "--loss", "cauchy", "--loss-scale", "2", "--threads", "2"],
                      dict(refine_principal_point=True, refine_extra_params=False,
                           hold_poses=[13, "img_0004.png"], loss="cauchy", loss_scale=2.0, threads=2))


def test_refine_with_sbas_tests_is_sbarefines(tmp_path):
    text, _ = sbagen(tmp_path, "varK")
    r = same_as_sbarefine(tmp_path, text, "text",
                          ["--strategy", "sba", "--itmax", "5", "--mcon", "1", "--ncon", "3"],
                          dict(strategy="sba", itmax=5, mcon=1, ncon=3))
    assert r.strategy == "sba" and r.iterations == 5


def test_refine_with_a_tolerance_is_sbarefines(tmp_path):
    text, _ = sbagen(tmp_path)
    r = same_as_sbarefine(tmp_path, text, "text", ["--function-tolerance", "1e-4", "--intrinsics", "none"],
                          dict(function_tolerance=1e-4, refine_focal_length=False, refine_extra_params=False))
    assert r.strategy == "trust-region" and r.reason == pysba.Reason.REDUCTION


def test_refine_with_a_gradient_tolerance_is_sbarefines(tmp_path):
    # COLMAP 4's gradient_tolerance, 1e-4 unless given: a looser one stops on the gradient
    # (reason 1) at sbarefine's bits; opts with an eps1 of their own keep it.
    text, _ = sbagen(tmp_path)
    r = same_as_sbarefine(tmp_path, text, "text", ["--gradient-tolerance", "10"], dict(gradient_tolerance=10))
    assert r.strategy == "trust-region" and r.reason == pysba.Reason.GRADIENT
    model = pysba.read_colmap(text)
    _, default = pysba.refine_colmap(model)
    _, given = pysba.refine_colmap(model, opts=[1e-3, 1e-9, 1e-12, 1e-12, 0])
    _, same = pysba.refine_colmap(model, gradient_tolerance=1e-9)
    _, zero = pysba.refine_colmap(model, gradient_tolerance=0)
    assert default.iterations <= same.iterations <= zero.iterations
    assert given.iterations == same.iterations and given.rms_final == same.rms_final


def test_refine_with_rigs_is_sbarefines(tmp_path):
    r = same_as_sbarefine(tmp_path, rigged(tmp_path), "text", [], {})
    # Each frame got its image's refined pose: the reference camera's bit for bit.
    model = r.model
    assert model.frames[0].q.tobytes() == model.images[0].q.tobytes()
    assert model.frames[0].t.tobytes() == model.images[0].t.tobytes()


def test_frames_pose_the_images(tmp_path):
    # Frame 902 (rig 3, whose reference camera 102 image 16 is) moved: COLMAP 4 takes image 16's
    # pose from it, and so do write_colmap (the images file holds the frame's pose, whatever
    # the image's q and t say), read_colmap and refine_colmap.
    model = pysba.read_colmap(rigged(tmp_path))
    before = model.images[2].t.copy()
    model.frames[2].t = model.frames[2].t + [0.05, 0, 0]
    pysba.write_colmap(model, tmp_path / "out", "text")
    lines = (tmp_path / "out" / "images.txt").read_text().splitlines()
    assert float(lines[8].split()[5]) == model.frames[2].t[0] != before[0]
    assert pysba.read_colmap(tmp_path / "out").images[2].t.tolist() == model.frames[2].t.tolist()
    refined, _ = pysba.refine_colmap(model, hold_poses=[16])
    assert refined.images[2].t.tolist() == model.frames[2].t.tolist()


def test_the_strategy_run_by_default_is_the_one_documented(tmp_path, monkeypatch):
    # COLMAP's (Ceres's trust region), whatever SBA_STRATEGY says, where solve()'s is sba's.
    monkeypatch.setenv("SBA_STRATEGY", "sba-clean-retry")
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    assert pysba.refine_colmap(model)[1].strategy == "trust-region"
    assert pysba.refine_colmap(model, opts=[1e-3, 1e-12, 1e-12, 1e-12, 1e-9])[1].strategy == "sba-clean-retry"
    doc = " ".join(pysba.refine_colmap.__doc__.split())
    assert ('strategy None runs "trust-region" (COLMAP\'s Levenberg-Marquardt), whatever $SBA_STRATEGY says, '
            'unless opts[4] is given without function_tolerance: then solve()\'s default') in doc
    solve = " ".join(pysba.solve.__doc__.split())
    assert 'None: $SBA_STRATEGY, else "sba" (refine_colmap: "trust-region", COLMAP\'s, see there)' in solve


def test_threads_give_the_same_model(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    one, r1 = pysba.refine_colmap(model, threads=1)
    two, r2 = pysba.refine_colmap(model, threads=2)
    same_model(one, two)
    assert r1.info.tolist() == r2.info.tolist()


def test_point_errors_false_keeps_the_errors_given(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    model.points3D.error = np.arange(len(model.points3D), dtype=np.float64) + 0.25
    scored, r1 = pysba.refine_colmap(model)
    kept, r2 = pysba.refine_colmap(model, point_errors=False)
    # The same solve and coordinates; only the errors differ: each point's own mean
    # reprojection error against the ones it was given.
    assert r1.info.tolist() == r2.info.tolist()
    same_array(kept.points3D.xyz, scored.points3D.xyz, "xyz")
    same_array(kept.points3D.error, model.points3D.error, "error")
    assert np.all(scored.points3D.error < 2) and scored.points3D.error.tobytes() != model.points3D.error.tobytes()
    with pytest.raises(TypeError, match="point_errors must be a bool, got int"):
        pysba.refine_colmap(model, point_errors=0)


def test_progress_stops_with_the_model_so_far(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    seen = []
    stopped, r = pysba.refine_colmap(model, progress=lambda s: seen.append(s.iteration) or s.iteration == 2)
    assert seen == [1, 2] and r.reason == pysba.Reason.USER and r.iterations == 2
    two, _ = pysba.refine_colmap(model, itmax=2)
    same_model(stopped, two)


def test_verbose_shows_the_progress(tmp_path, capsys):
    # On stderr: the problem, a line per iteration (through the progress callback, the caller's
    # called too), the end; the solve is the same.
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    quiet, r = pysba.refine_colmap(model)
    assert capsys.readouterr().err == ""
    seen = []
    loud, again = pysba.refine_colmap(model, verbose=True, progress=lambda s: seen.append(s.iteration))
    same_model(loud, quiet)
    assert again.info.tolist() == r.info.tolist() and seen == list(range(1, r.iterations + 1))
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "refine_colmap: 6 images, 6 cameras, 60 points, 250 observations"
    assert r.rms_final == math.sqrt(r.sq_error_final / 250)
    assert len(lines) == r.iterations + 2
    for k, line in enumerate(lines[1:-1]):
        assert re.fullmatch(rf"refine_colmap: iteration {k + 1}: RMS \S+ px, mu \S+, step \S+, \S+ s", line), line
    assert f"RMS {r.rms_final:.6g} px," in lines[-2]
    assert lines[-1] == (f"refine_colmap: RMS {r.rms_initial:.6g} px -> {r.rms_final:.6g} px in {r.iterations} "
                         f"iterations: {r.reason.text}")
    with pytest.raises(TypeError, match="verbose must be a bool, got int"):
        pysba.refine_colmap(model, verbose=1)


def test_keyboard_interrupt_keeps_the_model_so_far(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])

    def interrupt(state):
        if state.iteration == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as e:
        pysba.refine_colmap(model, progress=interrupt)
    r = e.value.result
    assert r.reason == pysba.Reason.USER and r.iterations == 2
    same_model(r.model, pysba.refine_colmap(model, itmax=2)[0])


def test_itmax_0_gives_the_model_as_given(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    same, _ = pysba.refine_colmap(model, itmax=0)
    same_model(same, model)


# ---- refusals ----

def test_unreadable_models_raise_oserror(tmp_path):
    with pytest.raises(FileNotFoundError):
        pysba.read_colmap(tmp_path / "absent")
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        pysba.read_colmap(tmp_path / "file")
    with pytest.raises(OSError, match=re.escape(f"{tmp_path}: no COLMAP model (cameras.txt or cameras.bin)")):
        pysba.read_colmap(tmp_path)
    text, _ = sbagen(tmp_path)
    (text / "images.txt").unlink()
    (text / "images.txt").mkdir()
    with pytest.raises(OSError, match=re.escape(f"{text}/images.txt: is a directory")):
        pysba.read_colmap(text)
    with pytest.raises(TypeError, match="path must be a str, bytes or os.PathLike, got int"):
        pysba.read_colmap(3)


def test_bad_models_raise_the_readers_message(tmp_path):
    text, binary = sbagen(tmp_path)
    lines = (text / "cameras.txt").read_text().splitlines()
    lines[4] = lines[4].replace("OPENCV", "OPENCVX")
    (text / "cameras.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=re.escape(f"{text}/cameras.txt:5: unknown camera model 'OPENCVX'")):
        pysba.read_colmap(text)
    (binary / "rigs.bin").write_bytes(b"\0" * 8)
    message = f"{binary}: rigs.bin without frames.bin: COLMAP 4 refuses"
    with pytest.raises(ValueError, match=re.escape(message)):
        pysba.read_colmap(binary)


def broken(tmp_path, change):
    model = pysba.read_colmap(rigged(tmp_path))
    change(model)
    return model


def set_attr(obj, name, value):
    setattr(obj, name, value)


@pytest.mark.parametrize("change, error, message", [
    (lambda m: set_attr(m.images[0], "camera_id", 999), ValueError,
     "model: image 10 uses camera 999, which cameras does not hold"),
    (lambda m: m.images[0].q.__setitem__(0, np.nan), ValueError, r"images[0].q[0] is not finite (nan)"),
    (lambda m: set_attr(m.images[0], "q", np.zeros(4)), ValueError,
     "model: image 10: the quaternion is zero"),
    (lambda m: set_attr(m.images[0], "t", [1, 2]), ValueError, "images[0].t must have shape (3,), got (2,)"),
    (lambda m: set_attr(m.images[1], "name", " x"), ValueError, "model: image 13: the name \" x\" is empty"),
    (lambda m: set_attr(m.images[1], "name", b"x"), TypeError, "images[1].name must be a str, got bytes"),
    (lambda m: set_attr(m.images[1], "id", 10), ValueError, "model: image 10 appears twice"),
    (lambda m: set_attr(m.images[1], "id", 2**32), ValueError,
     "images[1].id must be in [0, 4294967295], got 4294967296"),
    (lambda m: set_attr(m.images[1], "id", 13.0), TypeError, "images[1].id must be an int, got float"),
    (lambda m: set_attr(m.images[1], "point3D_ids", m.images[1].point3D_ids[:-1]), ValueError,
     "images[1].point3D_ids must have shape ("),
    (lambda m: m.images[1].point3D_ids.__setitem__(1, 12345), ValueError,
     "model: image 13 POINTS2D 1 names point 12345, which points3D does not hold"),
    (lambda m: set_attr(m.cameras[0], "model", "PINHOLE"), ValueError,
     "model: camera 100: PINHOLE has 4 parameters, found 8"),
    (lambda m: set_attr(m.cameras[0], "model", "PINHOLEX"), ValueError,
     "cameras[0].model: unknown camera model 'PINHOLEX' (COLMAP's are SIMPLE_PINHOLE, PINHOLE,"),
    (lambda m: m.cameras[0].params.__setitem__(1, -2), ValueError,
     "model: camera 100: OPENCV's fy must be positive, got -2"),
    (lambda m: (set_attr(m.cameras[0], "model", "EQUIRECTANGULAR"), set_attr(m.cameras[0], "params", [0.0, 480])),
     ValueError, "model: camera 100: EQUIRECTANGULAR's w must be positive, got 0"),
    (lambda m: set_attr(m.cameras[0], "width", -1), ValueError,
     "cameras[0].width must be in [0, 18446744073709551615], got -1"),
    (lambda m: set_attr(m.points3D, "rgb", np.full((60, 3), 256)), ValueError,
     "points3D.rgb[0, 0] = 256 is not in [0, 255]"),
    (lambda m: set_attr(m.points3D, "xyz", m.points3D.xyz.astype(str)), TypeError,
     "points3D.xyz must be an array of numbers, got an array of <U"),
    (lambda m: set_attr(m.points3D, "ids", m.points3D.ids.astype(float)), TypeError,
     "points3D.ids must be an array of integers, got an array of float64"),
    (lambda m: m.points3D.ids.__setitem__(0, pysba.NO_POINT3D), ValueError,
     "model: POINT3D_ID -1 is not an identifier"),
    (lambda m: m.points3D.track_offsets.__setitem__(1, 0), ValueError,
     "model: point 1000 has an empty track"),
    (lambda m: m.points3D.track_offsets.__setitem__(1, 10**6), ValueError,
     "points3D.track_offsets must rise from 0 to len(track_image_ids) = "),
    (lambda m: set_attr(m, "frames", None), ValueError, "rigs and frames go together"),
    (lambda m: set_attr(m.rigs[0].sensors[0], "q", [1, 0, 0, 0]), ValueError,
     "rigs[0].sensors[0]: q and t go together"),
    (lambda m: set_attr(m.rigs[0], "sensors", [pysba.ColmapSensor("CAMERA", 100, [1, 0, 0, 0], [0, 0, 0])] +
                        m.rigs[0].sensors[1:]),
     ValueError, "model: rig 1: its reference sensor CAMERA 100 has a pose in the rig"),
    (lambda m: set_attr(m.rigs[0].sensors[2], "type", "LIDAR"), ValueError,
     "rigs[0].sensors[2].type must be 'CAMERA' or 'IMU', got 'LIDAR'"),
    (lambda m: m.rigs[0].sensors.append(m.rigs[0].sensors[1]), ValueError,
     "model: rig 1 lists CAMERA 101 twice"),
    (lambda m: m.rigs[1].sensors.append(m.rigs[0].sensors[1]), ValueError,
     "model: CAMERA 101 is a sensor of rig 1 and of rig 3: a sensor belongs to one rig"),
    (lambda m: m.frames[0].data.append(("CAMERA", 100)), ValueError,
     "frames[0].data[2] must be (type, sensor_id, data_id), got 2 values"),
    (lambda m: m.frames[0].data.append(("IMU", 7, 55)), ValueError, "model: frame 900 lists IMU 7 55 twice"),
    (lambda m: m.frames[0].data.append(("CAMERA", 102, 16)), ValueError,
     "model: frame 900 holds data of CAMERA 102, which rig 1 does not hold"),
    (lambda m: set_attr(m.frames[1], "id", 900), ValueError, "model: frame 900 appears twice"),
    (lambda m: set_attr(m.frames[1], "q", [0, 0, 0, 0]), ValueError,
     "model: frame 901: the quaternion is zero"),
    (lambda m: set_attr(m.rigs[0].sensors[1], "q", [0, 0, 0, 0]), ValueError,
     "model: rig 1: the quaternion of CAMERA 101 is zero"),
    (lambda m: set_attr(m.rigs[1], "id", 1), ValueError, "model: rig 1 appears twice"),
    (lambda m: set_attr(m.cameras[1], "id", 100), ValueError, "model: camera 100 appears twice"),
    (lambda m: m.points3D.ids.__setitem__(1, 1000), ValueError, "model: point 1000 appears twice"),
    (lambda m: set_attr(m, "images", 3), TypeError, "images must be a list, got int"),
    (lambda m: set_attr(m.cameras[1], "id", 2**32 - 1), ValueError,
     "model: camera 4294967295: CAMERA_ID 4294967295 is COLMAP's invalid id (kInvalidCameraId), which COLMAP "
     "refuses"),
    (lambda m: set_attr(m.images[1], "id", 2**32 - 1), ValueError,
     "model: image 4294967295: IMAGE_ID 4294967295 is COLMAP's invalid id (kInvalidImageId)"),
    (lambda m: set_attr(m.rigs[1], "id", 2**32 - 1), ValueError,
     "model: rig 4294967295: RIG_ID 4294967295 is COLMAP's invalid id (kInvalidRigId)"),
    (lambda m: set_attr(m.frames[1], "id", 2**32 - 1), ValueError,
     "model: frame 4294967295: FRAME_ID 4294967295 is COLMAP's invalid id (kInvalidFrameId)"),
])
def test_models_the_reader_would_refuse(tmp_path, change, error, message):
    model = broken(tmp_path, change)
    with pytest.raises(error, match=re.escape(message)):
        pysba.write_colmap(model, tmp_path / "out", "binary")
    with pytest.raises(error, match=re.escape(message)):
        pysba.refine_colmap(model)
    assert not (tmp_path / "out").exists()


def test_write_refusals(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    with pytest.raises(ValueError, match="encoding must be 'text' or 'binary', got 'json'"):
        pysba.write_colmap(model, tmp_path / "out", "json")
    with pytest.raises(TypeError, match=re.escape("model must be a pysba.ColmapModel or a pycolmap.Reconstruction, "
                                                  "got dict")):
        pysba.write_colmap({}, tmp_path / "out")
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError, match=re.escape(f"{tmp_path}/file")):
        pysba.write_colmap(model, tmp_path / "file")
    assert (tmp_path / "file").read_text() == "x"


def two_image_frame(tmp_path):
    """rigged()'s model with frame 900 holding images 10 and 13 (rig 1's two cameras exposed
    together), written as text."""
    model = pysba.read_colmap(rigged(tmp_path))
    model.frames[0].data.append(model.frames[1].data[0])
    model.frames.pop(1)
    pysba.write_colmap(model, tmp_path / "rig2", "text")
    return tmp_path / "rig2"


# The two images were not taken by a rig: the more of the rig is held, the worse they fit (the
# frames' rotations held, or the frames' poses, which the noise moved, held altogether).
@pytest.mark.parametrize("args, kw, rms", [
    ([], {}, (0.52, 0.54)),
    (["--constant-rig-from-world-rotation", "1"],
     dict(constant_rig_from_world_rotation=True), (1.2, 1.25)),
    (["--refine-rig-from-world", "0", "--solver", "sparse-chol"],
     dict(refine_rig_from_world=False, solver="sparse-chol"), (6.4, 6.6))])
def test_refine_a_frame_of_two_images_is_sbarefines(tmp_path, args, kw, rms):
    r = same_as_sbarefine(tmp_path, two_image_frame(tmp_path), "text", args, kw)
    # Image 10 (camera 100, the rig's reference) has its frame's pose bit for bit; image 13
    # (camera 101) its frame's composed with the camera's pose in the rig.
    frame = r.model.frames[0]
    assert [d[2] for d in frame.data if d[0] == "CAMERA"] == [10, 13]
    image = {im.id: im for im in r.model.images}
    assert frame.q.tobytes() == image[10].q.tobytes() and frame.t.tobytes() == image[10].t.tobytes()
    assert not np.array_equal(frame.t, image[13].t)
    assert rms[0] < r.rms_final < rms[1] and r.rms_initial > 16


def test_refine_refusals(tmp_path):
    source = rigged(tmp_path)
    model = pysba.read_colmap(source)
    for kw, error, message in [
            (dict(hold_poses=[10, "nope.png"]), ValueError,
             "hold_poses[1]: no image has the NAME 'nope.png'"),
            (dict(hold_poses=[11]), ValueError, "hold_poses[0]: no image has the IMAGE_ID 11"),
            (dict(hold_poses=[True]), TypeError,
             "hold_poses[0] must be an IMAGE_ID (int) or a NAME (str), got bool"),
            (dict(hold_poses="img_0000.png"), ValueError, "hold_poses must be 'all' or a list of IMAGE_IDs"),
            # Not read as lists: bytes as IMAGE_IDs (bytes([10]) as image 10), a dict as its keys.
            (dict(hold_poses=bytes([10])), TypeError,
             "hold_poses must be 'all' or a list of IMAGE_IDs (ints) and NAMEs (strs), got bytes"),
            (dict(hold_poses=bytearray([10])), TypeError,
             "hold_poses must be 'all' or a list of IMAGE_IDs (ints) and NAMEs (strs), got bytearray"),
            (dict(hold_poses={10: True}), TypeError,
             "hold_poses must be 'all' or a list of IMAGE_IDs (ints) and NAMEs (strs), got dict"),
            (dict(refine_focal_length=1), TypeError, "refine_focal_length must be a bool, got int"),
            (dict(refine_sensor_from_rig=None), TypeError, "refine_sensor_from_rig must be a bool, got NoneType"),
            (dict(function_tolerance=-1), ValueError, "function_tolerance must be finite and >= 0, got -1"),
            (dict(function_tolerance="0"), TypeError, "function_tolerance must be a number, got str"),
            (dict(gradient_tolerance=-1e-3), ValueError, "gradient_tolerance must be finite and >= 0, got -0.001"),
            (dict(gradient_tolerance=math.inf), ValueError, "gradient_tolerance must be finite and >= 0, got inf"),
            (dict(opts=[1e-3]), ValueError, "opts must hold 5 values"),
            (dict(mcon=7), ValueError, "mcon must be in [0, 6], got 7"),
            (dict(threads=1.5), TypeError, "threads must be an int, got float")]:
        with pytest.raises(error, match=re.escape(message)):
            pysba.refine_colmap(model, **kw)
    for f in (pysba.refine_colmap, lambda m: pysba.write_colmap(m, tmp_path / "out")):
        for path in (str(source), source):
            with pytest.raises(TypeError, match=re.escape(
                    f"model must be a pysba.ColmapModel or a pycolmap.Reconstruction, got {type(path).__name__} "
                    f"(pysba.read_colmap(path) reads the model in a folder)")):
                f(path)
    empty = pysba.ColmapModel()
    with pytest.raises(ValueError, match="model: the model has no images or no points"):
        pysba.refine_colmap(empty)


def test_hold_refusals(tmp_path):
    # The exact message and type; the ids are rigged()'s (cameras 100 to 105, points 1000 + 7i).
    model = pysba.read_colmap(rigged(tmp_path))
    for kw, error, message in [
        # The first item that names nothing, wherever it is, whatever follows it.
        (dict(hold_intrinsics=[100, 7]), ValueError, "hold_intrinsics[1]: no camera has the CAMERA_ID '7'"),
        (dict(hold_intrinsics=[-1]), ValueError, "hold_intrinsics[0]: no camera has the CAMERA_ID '-1'"),
        (dict(hold_intrinsics=[2**32]), ValueError,
         "hold_intrinsics[0]: no camera has the CAMERA_ID '4294967296'"),
        (dict(hold_sensor_from_rig=[101, 99, -1]), ValueError,
         "hold_sensor_from_rig[1]: no camera has the CAMERA_ID '99'"),
        (dict(hold_sensor_from_rig=[101, -1, 99]), ValueError,
         "hold_sensor_from_rig[1]: no camera has the CAMERA_ID '-1'"),
        (dict(hold_points=[1000, 1007, 5, 1014, 6]), ValueError, "hold_points[2]: no point has the POINT3D_ID '5'"),
        (dict(hold_points=[1001]), ValueError, "hold_points[0]: no point has the POINT3D_ID '1001'"),
        (dict(hold_points=[2**64]), ValueError, "hold_points[0]: no point has the POINT3D_ID '18446744073709551616'"),
        (dict(hold_points=[1000, True]), TypeError, "hold_points[1] must be a POINT3D_ID (int), got bool"),
        (dict(hold_points=[1000.0]), TypeError, "hold_points[0] must be a POINT3D_ID (int), got float"),
        (dict(hold_intrinsics=["100"]), TypeError, "hold_intrinsics[0] must be a CAMERA_ID (int), got str"),
        (dict(hold_intrinsics="none"), ValueError,
         "hold_intrinsics must be 'all' or a list of CAMERA_IDs (ints), got 'none'"),
        (dict(hold_intrinsics=bytes([100])), TypeError,
         "hold_intrinsics must be 'all' or a list of CAMERA_IDs (ints), got bytes"),
        (dict(hold_sensor_from_rig={101: True}), TypeError,
         "hold_sensor_from_rig must be 'all' or a list of CAMERA_IDs (ints), got dict"),
        (dict(hold_points=1000), TypeError, "hold_points must be 'all' or a list of POINT3D_IDs (ints), got int"),
        (dict(hold_points=1000.5), TypeError,
         "hold_points must be 'all' or a list of POINT3D_IDs (ints), got float"),
    ]:
        with pytest.raises(Exception) as e:
            pysba.refine_colmap(model, **kw)
        assert type(e.value) is error and str(e.value) == message, kw


def test_held_poses_are_kept(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    refined, _ = pysba.refine_colmap(model, hold_poses=[13, "img_0004.png"])
    moved = [not (a.q.tobytes() == b.q.tobytes() and a.t.tobytes() == b.t.tobytes())
             for a, b in zip(model.images, refined.images)]
    assert moved == [True, False, True, True, False, True]
    # Any sequence of IDs and NAMEs (a tuple; numpy integers as IDs) names the same images.
    for given in ((13, "img_0004.png"), [np.int64(13), "img_0004.png"]):
        again, _ = pysba.refine_colmap(model, hold_poses=given)
        assert all(a.t.tobytes() == b.t.tobytes() for a, b in zip(refined.images, again.images))
    everything, _ = pysba.refine_colmap(model, hold_poses="all")
    assert all(a.t.tobytes() == b.t.tobytes() for a, b in zip(model.images, everything.images))


# COLMAP's other constants: the same lists as sbarefine's --hold-* options, the same bits.

def test_held_intrinsics_are_sbarefines(tmp_path):
    # Cameras 101 and 104 (OPENCV, each of one image) keep their parameters; the others move.
    text, _ = sbagen(tmp_path)
    r = same_as_sbarefine(tmp_path, text, "text", ["--hold-intrinsics", "101,104"],
                          dict(hold_intrinsics=[101, np.uint32(104)]))
    given = pysba.read_colmap(text)
    kept = [a.params.tobytes() == b.params.tobytes() for a, b in zip(given.cameras, r.model.cameras)]
    assert [c.id for c in given.cameras] == [100, 101, 102, 103, 104, 105]
    assert kept == [False, True, False, False, True, False]


def test_all_intrinsics_held_are_sbarefines(tmp_path):
    _, binary = sbagen(tmp_path, "fixed")
    r = same_as_sbarefine(tmp_path, binary, "binary", ["--hold-intrinsics", "all"], dict(hold_intrinsics="all"))
    assert r.model.cameras[0].params.tobytes() == pysba.read_colmap(binary).cameras[0].params.tobytes()


def quaternion_product(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def test_held_sensor_from_rig_is_sbarefines(tmp_path):
    # Camera 101's pose in rig 1, which frame 900 (images 10 and 13) refines when it is free:
    # two_image_frame's model, but that the pose is where image 13 is seen from image 10 (their
    # frames' poses in rigged()), so that holding it holds a pose that fits. Held where it does
    # not, the solve finds no minimum but with the points behind the two images, where COLMAP's
    # cost of them is zero.
    model = pysba.read_colmap(rigged(tmp_path))
    a, b = model.frames[0], model.frames[1]
    q = quaternion_product(b.q, a.q * np.array([1.0, -1.0, -1.0, -1.0]))
    rotate = quaternion_product(quaternion_product(q, np.concatenate([[0.0], a.t])), q * np.array([1, -1, -1, -1]))
    sensor = model.rigs[0].sensors[1]
    sensor.q, sensor.t = q, b.t - rotate[1:]
    model.frames[0].data.append(model.frames[1].data[0])
    model.frames.pop(1)
    pysba.write_colmap(model, tmp_path / "fit", "text")
    source = tmp_path / "fit"
    given = pysba.read_colmap(source)
    free, _ = pysba.refine_colmap(given)
    sensor = given.rigs[0].sensors[1]
    assert sensor.id == 101 and free.rigs[0].sensors[1].t.tobytes() != sensor.t.tobytes()
    for n, (arg, kw) in enumerate((("101", (101,)), ("all", "all"))):
        (tmp_path / str(n)).mkdir()
        r = same_as_sbarefine(tmp_path / str(n), source, "text", ["--hold-sensor-from-rig", arg],
                              dict(hold_sensor_from_rig=kw))
        held = r.model.rigs[0].sensors[1]
        assert held.q.tobytes() == sensor.q.tobytes() and held.t.tobytes() == sensor.t.tobytes()
        # The frames still move.
        assert r.model.frames[0].t.tobytes() != given.frames[0].t.tobytes()


def test_held_points_are_sbarefines(tmp_path):
    # Points 1413, 1000 and 1007 (rows 59, 0 and 1) and, with ncon 3, the first three (1014, row
    # 2, too) keep their coordinates; the others move.
    text, _ = sbagen(tmp_path)
    given = pysba.read_colmap(text)
    ids = given.points3D.ids
    assert ids[[0, 1, 59]].tolist() == [1000, 1007, 1413]
    r = same_as_sbarefine(tmp_path, text, "text", ["--hold-points", "1413,1000,1007", "--ncon", "3"],
                          dict(hold_points=ids[[59, 0, 1]], ncon=3))
    kept = [a.tobytes() == b.tobytes() for a, b in zip(given.points3D.xyz, r.model.points3D.xyz)]
    assert [k for k, same in enumerate(kept) if same] == [0, 1, 2, 59]
    everything, _ = pysba.refine_colmap(given, hold_points="all")
    assert everything.points3D.xyz.tobytes() == given.points3D.xyz.tobytes()


def test_a_missing_id_is_sbarefines_message(tmp_path):
    # The same words as sbarefine's, which reads the list by the same code.
    text, _ = sbagen(tmp_path)
    run = subprocess.run([program("PYSBA_SBAREFINE"), str(text), "--hold-points", "1000,5"],
                         capture_output=True, text=True)
    assert run.returncode == 1
    assert run.stderr.splitlines()[0] == f"sbarefine: --hold-points: {text}: no point has the POINT3D_ID '5'"
    with pytest.raises(ValueError) as e:
        pysba.refine_colmap(pysba.read_colmap(text), hold_points=[1000, 5])
    assert str(e.value) == "hold_points[1]: no point has the POINT3D_ID '5'"


def without_observations(model, image_id):
    """The model with image image_id's observations gone (its keypoints observe no point, and a
    point only it saw goes)."""
    for im in model.images:
        if im.id == image_id:
            im.point3D_ids = np.full_like(im.point3D_ids, pysba.NO_POINT3D)
    p = model.points3D
    keep, offsets, images, idxs = [], [0], [], []
    for k in range(len(p)):
        ids, at = p.track(k)
        kept = ids != image_id
        if kept.any():
            keep.append(k)
            images += ids[kept].tolist()
            idxs += at[kept].tolist()
            offsets.append(len(images))
    model.points3D = pysba.ColmapPoints3D(p.ids[keep], p.xyz[keep], p.rgb[keep], p.error[keep],
                                          np.array(offsets, np.uint64), np.array(images, np.uint32),
                                          np.array(idxs, np.uint32))
    return model


def test_a_held_image_that_sees_no_point_holds_its_frame(tmp_path):
    # Frame 900 holds images 10 (camera 100, rig 1's reference) and 13 (camera 101), which sees
    # no point: it keeps its place in the frame, and moves with it unless it is held.
    model = without_observations(pysba.read_colmap(two_image_frame(tmp_path)), 13)
    pysba.write_colmap(model, tmp_path / "two", "binary")
    model = pysba.read_colmap(tmp_path / "two")
    free, _ = pysba.refine_colmap(model)
    assert free.images[1].t.tobytes() != model.images[1].t.tobytes()
    held, _ = pysba.refine_colmap(model, hold_poses=[13])
    for a, b in ((held.images[1], model.images[1]), (held.frames[0], model.frames[0]),
                 (held.rigs[0].sensors[1], model.rigs[0].sensors[1])):
        assert a.q.tobytes() == b.q.tobytes() and a.t.tobytes() == b.t.tobytes()
    assert held.images[2].t.tobytes() != model.images[2].t.tobytes()


def test_an_overflowing_projection_is_named(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    model.cameras[1].params[4] = 1e200  # camera 101's k1
    for itmax in (100, 0):  # the library evaluates the error with itmax 0 too
        with pytest.raises(ValueError, match=re.escape("model: image 13 (img_0001.png), camera 101 (OPENCV): point ")
                           + ".* px, where its squared reprojection error is not finite$"):
            pysba.refine_colmap(model, itmax=itmax)


def with_unposed_frame(model):
    """The model with a frame of rig 1 (camera 100's) without a pose, as pycolmap holds a frame it
    has not registered, and its image 7, which observes no point, both first."""
    model.images.insert(0, pysba.ColmapImage(7, "unposed.png", 100, None, None, np.array([[1.5, 2.5], [3.0, 4.0]]),
                                             np.full(2, pysba.NO_POINT3D, np.uint64)))
    model.frames.insert(0, pysba.ColmapFrame(7, 1, None, None, [("CAMERA", 100, 7)]))
    return model


def test_frames_without_a_pose_are_neither_written_nor_refined(tmp_path):
    source = rigged(tmp_path)
    model, unposed = pysba.read_colmap(source), with_unposed_frame(pysba.read_colmap(source))
    pysba.write_colmap(unposed, tmp_path / "a", "binary")
    pysba.write_colmap(model, tmp_path / "b", "binary")
    assert files(tmp_path / "a") == files(tmp_path / "b")
    # Held by IMAGE_ID and by row (mcon): the rows of the model given, the unposed image among them.
    mine, r = pysba.refine_colmap(unposed, hold_poses=[13], mcon=1)
    theirs, again = pysba.refine_colmap(model, hold_poses=[13], mcon=1)
    assert r.info.tolist() == again.info.tolist()
    first, frame = mine.images.pop(0), mine.frames.pop(0)
    same_model(mine, theirs)
    given = unposed.images[0]
    assert first is not given and (first.id, first.name, first.q, first.t) == (7, "unposed.png", None, None)
    same_array(first.points2D, given.points2D, "points2D")
    same_array(first.point3D_ids, given.point3D_ids, "point3D_ids")
    assert frame is not unposed.frames[0] and (frame.id, frame.q, frame.data) == (7, None, [("CAMERA", 100, 7)])


def test_frames_without_a_pose_that_pycolmap_would_refuse(tmp_path):
    source = rigged(tmp_path)
    for change, message in [
            (lambda m: set_attr(m.images[0], "t", [0.0, 0, 0]),
             "images[0]: q and t go together: both None (no pose: not registered) or both given"),
            (lambda m: set_attr(m.frames[0], "q", [1.0, 0, 0, 0]),
             "frames[0]: q and t go together: both None (no pose: not registered) or both given"),
            (lambda m: m.images[0].point3D_ids.__setitem__(1, 1007),
             "images[0] has no pose (not registered) but observes point 1007 (point3D_ids[1]): an image without "
             "a pose observes no point"),
            (lambda m: m.frames[0].data.append(("CAMERA", 100, 10)),
             "images[1] has a pose, but its frame 7 has none: COLMAP 4 registers the images of a frame with it"),
            (lambda m: m.frames[1].data.append(("CAMERA", 100, 7)),
             "images[0] has no pose (q and t None), but its frame 900 has one: COLMAP 4 registers the images of "
             "a frame with it"),
            (lambda m: m.frames[0].data.pop(),
             "images[0] has no pose (q and t None) and is in no frame"),
            (lambda m: m.frames[0].data.append(("CAMERA", 101, 8)),
             "frames[0] has no pose (q and t None), but its image 8 is none of the images without one")]:
        model = with_unposed_frame(pysba.read_colmap(source))
        change(model)
        for f in (lambda: pysba.write_colmap(model, tmp_path / "out"), lambda: pysba.refine_colmap(model)):
            with pytest.raises(ValueError, match=re.escape(message)):
                f()
    plain = pysba.read_colmap(sbagen(tmp_path / "plain")[0])
    plain.images[0].q = plain.images[0].t = None
    with pytest.raises(ValueError, match=re.escape("images[0] has no pose (q and t None), which only an image of a "
                                                   "frame without one may have, and the model has no frames")):
        pysba.write_colmap(plain, tmp_path / "out")


def test_the_conversions_point_to_the_refinement_in_memory():
    # from_pycolmap and to_pycolmap write and read whole models through files: their docs say
    # so and send the user to refine_colmap, which reads a Reconstruction in memory and can
    # refine it in place.
    for f in (pysba.from_pycolmap, pysba.to_pycolmap):
        doc = " ".join(f.__doc__.split())
        assert "through files" in doc and ":func:`refine_colmap` of a Reconstruction" in doc, f.__name__
    doc = " ".join(pysba.refine_colmap.__doc__.split())
    assert "in memory (no file" in doc and "``in_place=True``" in doc


def test_pycolmap_is_named_when_missing(monkeypatch):
    monkeypatch.setitem(sys.modules, "pycolmap", None)  # import pycolmap raises ImportError
    for f in (pysba.from_pycolmap, pysba.to_pycolmap):
        with pytest.raises(ImportError, match=r"need pycolmap \(pip install pycolmap\)"):
            f(pysba.ColmapModel())


# ---- covariances: sbarefine --covariance's file ----

def covariance_file(path):
    """sbarefine's --covariance file as refine_colmap's colmap_covariance: {kind: {id: array}},
    the coordinates, and SIGMA2's line."""
    kinds = {"IMAGE": "images", "FRAME": "frames", "SENSOR": "sensors", "CAMERA": "cameras", "POINT": "points"}
    blocks = {k: {} for k in kinds.values()}
    coords = {k: {} for k in kinds.values()}
    head = None
    for line in path.read_text().splitlines():
        w = line.split()
        if line.startswith("#"):
            continue
        if w[0] == "SIGMA2":
            head = (float(w[1]), int(w[3]), int(w[5]))
            continue
        kind, named = kinds[w[0]], w[0] == "IMAGE"
        names = w[3 if named else 2].split(",")
        values = np.array([float(v) for v in w[4 if named else 3:]])
        blocks[kind][int(w[1])] = values.reshape(len(names), len(names))
        coords[kind][int(w[1])] = tuple(int(c) if kind == "cameras" else c for c in names)
    return blocks, coords, head


def same_covariances(tmp_path, model_dir, args, kw):
    out = tmp_path / "cov.txt"
    sbarefine(model_dir, tmp_path / "sbarefine",
              [*args, "--gauge", kw.get("gauge") or "none", "--covariance", out, "--covariance-points"])
    blocks, coords, head = covariance_file(out)
    _, result = pysba.refine_colmap(pysba.read_colmap(model_dir), covariance=True, covariance_points=True, **kw)
    c = result.colmap_covariance
    assert math.isclose(c["sigma2"], head[0], rel_tol=1e-12) and (c["rank"], c["nfree"]) == head[1:]
    for kind, by_id in blocks.items():
        assert sorted(c[kind]) == sorted(by_id), kind
        assert c["coords"][kind] == coords[kind], kind
        for k, a in by_id.items():
            # The same computation; the bound, not the bits, for any BLAS and thread count.
            assert c[kind][k].shape == (len(coords[kind][k]),) * 2, (kind, k)
            assert np.abs(c[kind][k] - a).max() <= 1e-9 * np.abs(a).max(), (kind, k)
            assert np.array_equal(a, a.T) and (np.diag(a) > 0).all(), (kind, k)
    return c


def test_covariances_are_sbarefines(tmp_path):
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    held = [model.images[0].id, model.images[1].id]
    c = same_covariances(tmp_path, text, ["--hold-poses", f"{held[0]},{held[1]}"], dict(hold_poses=held))
    # Each image's pose but the held ones', every camera's focal length and distortion (the
    # principal point held), every point; the gauge fixed by the two held poses.
    assert sorted(c["images"]) == sorted(im.id for im in model.images[2:])
    assert all(v == ("rx", "ry", "rz", "tx", "ty", "tz") for v in c["coords"]["images"].values())
    assert sorted(c["cameras"]) == sorted(cam.id for cam in model.cameras)
    assert all(2 not in v and 3 not in v for v in c["coords"]["cameras"].values())
    assert len(c["points"]) == len(model.points3D) and c["rank"] == c["nfree"]
    assert not c["frames"] and not c["sensors"]


def test_covariance_damping_is_pycolmaps_by_default(tmp_path):
    # pycolmap's BACovarianceOptions.damping (1e-8) is the default of both front ends, so that
    # their blocks are a COLMAP user's numbers without an option; 0 is J^T J's own inverse.
    text, _ = sbagen(tmp_path)
    held = [im.id for im in pysba.read_colmap(text).images[:2]]
    files = {}
    for name, extra in (("default", []), ("1e-8", ["--covariance-damping", "1e-8"]),
                        ("0", ["--covariance-damping", "0"])):
        out = tmp_path / f"cov-{name}.txt"
        sbarefine(text, tmp_path / name, ["--itmax", "0", "--hold-poses", f"{held[0]},{held[1]}",
                                          "--covariance", out, *extra])
        files[name] = out.read_text()
    assert files["default"] == files["1e-8"] and files["default"] != files["0"]
    runs = {}
    for name, kw in (("default", {}), ("1e-8", dict(covariance_damping=1e-8)), ("0", dict(covariance_damping=0.0))):
        _, result = pysba.refine_colmap(pysba.read_colmap(text), itmax=0, hold_poses=held, covariance=True, **kw)
        runs[name] = result.colmap_covariance["images"]
    same = [np.array_equal(runs["default"][k], runs["1e-8"][k]) for k in runs["default"]]
    moved = [not np.array_equal(runs["default"][k], runs["0"][k]) for k in runs["default"]]
    assert all(same) and any(moved)


def test_covariances_with_rigs_are_sbarefines(tmp_path):
    # sbagen's model as one rig of cameras 100 (its reference) and 101, three frames of two
    # images: images 0, 2, 4 taken with camera 100, 1, 3, 5 with camera 101.
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    for j, im in enumerate(model.images):
        im.camera_id = 100 + j % 2
    model.cameras = [cam for cam in model.cameras if cam.id in (100, 101)]
    rig = tmp_path / "rig"
    pysba.write_colmap(model, rig, "text")
    q = " ".join(repr(v) for v in rad(0.01) + [0.01, 0.0, 0.0])
    frames = ["# Frame list"]
    for f in range(3):
        a, b = model.images[2 * f], model.images[2 * f + 1]
        pose = " ".join(repr(float(v)) for v in list(a.q) + list(a.t))
        frames.append(f"{900 + f} 1 {pose} 2 CAMERA 100 {a.id} CAMERA 101 {b.id}")
    (rig / "rigs.txt").write_text(f"# Rig list\n1 2 CAMERA 100 CAMERA 101 1 {q}\n")
    (rig / "frames.txt").write_text("\n".join(frames) + "\n")
    c = same_covariances(tmp_path, rig, ["--hold-poses", str(model.images[0].id)],
                         dict(hold_poses=[model.images[0].id]))
    # Every image's pose but the one held whole (camera 100's in frame 900: camera 101's moves
    # with the camera's pose in the rig), the free frames' poses and camera 101's in the rig.
    assert sorted(c["images"]) == sorted(im.id for im in model.images[1:])
    assert sorted(c["frames"]) == [901, 902] and sorted(c["sensors"]) == [101]
    assert sorted(c["cameras"]) == [100, 101]


# ---- position priors (COLMAP 4's pose-prior adjustment) ----

def centre(image):
    """An image's projection centre, -R^T t."""
    w, x, y, z = np.asarray(image.q, dtype=np.float64) / np.linalg.norm(image.q)
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return -R.T @ np.asarray(image.t, dtype=np.float64)


def gps(model):
    """Priors a similarity away from the model's centres (scale 2, a turn, a shift) with a
    known error of a few centimetres, as dicts and as sbarefine's text file."""
    c, s = math.cos(0.4), math.sin(0.4)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    priors = []
    for k, im in enumerate(model.images):
        noise = 0.03 * np.array([math.sin(3 * k), math.cos(5 * k), math.sin(7 * k)])
        priors.append({"image_id": im.id, "position": 2 * R @ centre(im) + [100, 50, 10] + noise,
                       "covariance": np.diag([0.01, 0.01, 0.04])})
    text = "".join(f"{im.name} " + " ".join(repr(float(v)) for v in p["position"]) + " " +
                   " ".join(repr(float(v)) for v in p["covariance"].ravel()) + " CARTESIAN\n"
                   for im, p in zip(model.images, priors))
    return priors, text


def test_pose_priors_are_sbarefines(tmp_path):
    # The same priors through refine_colmap and sbarefine's --pose-priors: the same refined
    # model to the bit, the same costs apart; the model now in the priors' frame.
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    priors, lines = gps(model)
    (tmp_path / "gps.txt").write_text(lines)
    report = sbarefine(text, tmp_path / "sbarefine", ["--pose-priors", tmp_path / "gps.txt"])
    refined, result = pysba.refine_colmap(model, pose_priors=priors)
    pysba.write_colmap(refined, tmp_path / "pysba", "text")
    assert files(tmp_path / "pysba") == files(tmp_path / "sbarefine")
    assert result.prior_cost_final == report["prior_cost"]["final"]
    assert result.projection_cost_final == report["projection_cost"]["final"]
    assert report["priors"] == len(model.images)
    scale = re.search(r"moved onto them by a similarity of scale ([0-9.]+) \(6 of 6 within", result.colmap_priors)
    assert scale and abs(float(scale.group(1)) - 2) < 0.01, result.colmap_priors
    for im, p in zip(refined.images, priors):
        assert np.linalg.norm(centre(im) - p["position"]) < 0.3
    # Fewer than 3 priors: as without priors, to the bit.
    few, _ = pysba.refine_colmap(model, pose_priors=priors[:2])
    plain, _ = pysba.refine_colmap(model)
    pysba.write_colmap(few, tmp_path / "few", "text")
    pysba.write_colmap(plain, tmp_path / "plain", "text")
    assert files(tmp_path / "few") == files(tmp_path / "plain")


@pytest.mark.parametrize("kw, error, message", [
    (dict(pose_priors=5), TypeError, "pose_priors must be a database path or a sequence of priors, got int"),
    (dict(pose_priors=[[1, 2, 3]]), TypeError, "pose_priors[0] must be a pycolmap.PosePrior or a dict, got list"),
    (dict(pose_priors=[{"image_id": 10}]), ValueError, "pose_priors[0] needs 'image_id' and 'position'"),
    (dict(pose_priors=[{"image_id": 10, "position": [1, 2], "x": 1}]), ValueError,
     "pose_priors[0] has an unknown key 'x'"),
    (dict(pose_priors=[{"image_id": -1, "position": [1, 2, 3]}]), ValueError,
     "pose_priors[0]: image_id must be an IMAGE_ID (an int in 0..4294967295), got -1"),
    (dict(pose_priors=[{"image_id": 10, "position": [1, 2]}]), ValueError,
     "pose_priors[0]: position must have 3 values, got 2"),
    (dict(pose_priors=[{"image_id": 10, "position": [1, 2, 3], "coordinate_system": "ECEF"}]), ValueError,
     "pose_priors[0]: coordinate_system must be 'CARTESIAN' or 'WGS84', got 'ECEF'"),
    (dict(pose_priors=[{"image_id": 10, "position": [1, 2, math.inf]}]), ValueError,
     "pose_priors[0]: its position is not finite"),
    (dict(pose_priors=[{"image_id": 10, "position": [1, 2, 3], "covariance": np.diag([1.0, -1.0, 1.0])}]),
     ValueError, "pose_priors[0]: its covariance is not symmetric positive definite"),
    (dict(prior_position_loss="huber"), ValueError, "prior_position_loss must be 'trivial' or 'cauchy', got 'huber'"),
    (dict(prior_position_fallback_stddev=0.0), ValueError, "prior_position_fallback_stddev must be finite and > 0"),
    (dict(alignment_max_error=-1.0), ValueError, "alignment_max_error must be finite and >= 0, got -1.0"),
])
def test_pose_priors_refused(tmp_path, kw, error, message):
    text, _ = sbagen(tmp_path)
    model = pysba.read_colmap(text)
    with pytest.raises(error) as e:
        pysba.refine_colmap(model, **kw)
    assert str(e.value).startswith(message), str(e.value)


def test_pose_priors_from_a_database_that_is_none(tmp_path):
    text, _ = sbagen(tmp_path)
    missing = tmp_path / "missing.db"
    with pytest.raises(ValueError, match="cannot open as an SQLite database"):
        pysba.refine_colmap(pysba.read_colmap(text), pose_priors=missing)
    assert not missing.exists()


# COLMAP 4's BundleAdjustmentConfig beyond the constants (pysba.colmap.bundle_adjustment's; its
# comparison with pycolmap's adjuster is tests/python/pycolmap_bundle_adjustment.py).

def test_config_refusals(tmp_path):
    model = pysba.read_colmap(rigged(tmp_path))
    for kw, error, message in [
        (dict(hold_frames=[900, 5]), ValueError, "hold_frames[1]: no frame with a pose has the FRAME_ID '5'"),
        (dict(images=[10, 11]), ValueError, "images[1]: no image with a pose has the IMAGE_ID '11'"),
        (dict(images=[]), ValueError, "images names no image: give None for every one"),
        (dict(variable_points=[1000, 1001]), ValueError, "variable_points[1]: no point has the POINT3D_ID '1001'"),
        (dict(images=[10.0]), TypeError, "images[0] must be an IMAGE_ID (int), got float"),
        (dict(gauge="two"), ValueError, "gauge must be None, 'two-cams' or 'three-points', got 'two'"),
        (dict(min_track_length=2.0), TypeError, "min_track_length must be an int, got float"),
        (dict(refine_points3D=1), TypeError, "refine_points3D must be a bool, got int"),
        (dict(images=[10], min_track_length=100), ValueError,
         "model: the configuration leaves no observation to refine"),
    ]:
        with pytest.raises(Exception) as e:
            pysba.refine_colmap(model, **kw)
        assert type(e.value) is error and str(e.value) == message, kw


def poses(model):
    return [(im.q.tobytes(), im.t.tobytes()) for im in model.images]


def test_images_outside_the_config_are_held(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    ids = [im.id for im in model.images]
    refined, result = pysba.refine_colmap(model, images=ids[:3])
    moved = [a != b for a, b in zip(poses(model), poses(refined))]
    assert moved == [True, True, True, False, False, False]
    # A point seen beyond the first three images is held; one seen by them alone is refined.
    p = model.points3D
    inside = np.array([set(p.track(k)[0].tolist()) <= set(ids[:3]) for k in range(len(p))])
    assert inside.any() and not inside.all()
    kept = np.all(refined.points3D.xyz == p.xyz, axis=1)
    assert np.array_equal(kept, ~inside)
    # With every point variable, every point moves, with every observation of its.
    everything, more = pysba.refine_colmap(model, images=ids[:3], variable_points="all")
    assert len(more.points) == len(p) and more.cameras.shape[0] == len(ids)
    assert poses(everything)[3:] == poses(model)[3:]
    assert not np.any(np.all(everything.points3D.xyz == p.xyz, axis=1))


def test_two_cams_gauge_holds_two_poses_at_the_same_minimum(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    free, a = pysba.refine_colmap(model, gauge=None)
    fixed, b = pysba.refine_colmap(model, gauge="two-cams")
    order = sorted(range(len(model.images)), key=lambda k: model.images[k].id)
    first, second = (model.images[k] for k in order[:2])
    held = fixed.images[order[0]]
    assert held.q.tobytes() == first.q.tobytes() and held.t.tobytes() == first.t.tobytes()
    kept = [fixed.images[order[1]].t[c].tobytes() == second.t[c].tobytes() for c in range(3)]
    assert sum(kept) == 1
    assert free.images[order[0]].t.tobytes() != first.t.tobytes()
    # The gauge moves no reprojection: the same minimum.
    assert b.rms_final == pytest.approx(a.rms_final, rel=1e-6)
    # Three points held are two coordinates more than the gauge has, as in COLMAP.
    three, c = pysba.refine_colmap(model, gauge="three-points")
    assert sum(a.tobytes() == b.tobytes() for a, b in zip(three.points3D.xyz, model.points3D.xyz)) == 3
    assert a.rms_final < c.rms_final < c.rms_initial


def test_min_track_length_and_refine_points3D(tmp_path):
    model = pysba.read_colmap(sbagen(tmp_path)[0])
    lengths = np.diff(model.points3D.track_offsets.astype(np.int64))
    refined, result = pysba.refine_colmap(model, min_track_length=int(np.median(lengths)) + 1)
    short = lengths <= np.median(lengths)
    assert short.any() and not short.all()
    kept = np.all(refined.points3D.xyz == model.points3D.xyz, axis=1)
    assert np.array_equal(kept, short)
    assert len(result.points) == int((~short).sum())
    held, _ = pysba.refine_colmap(model, refine_points3D=False)
    assert held.points3D.xyz.tobytes() == model.points3D.xyz.tobytes()
    assert poses(held) != poses(model)


def test_pysba_colmap_needs_pycolmap_to_run():
    import pysba.colmap
    try:
        import pycolmap  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pip install pycolmap"):
            pysba.colmap.bundle_adjustment(object())
    else:
        with pytest.raises(TypeError, match="reconstruction must be a pycolmap.Reconstruction, got object"):
            pysba.colmap.bundle_adjustment(object())
