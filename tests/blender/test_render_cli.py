"""`python -m platelight render scene.blend --out DIR`: a render killed (SIGKILL) in the middle of
the sequence, while it writes a frame, leaves only complete frames under their final names, and
a rerun renders the remaining frames only; bad input gets one sentence and exit status 2."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import support
from platelight.addon.exr_io import read_exr, write_exr
from composite_scene import add_camera, add_sphere, add_sun, grey_world

FRAMES = 10
PW, PH = 640, 360   # big enough that writing a frame takes a while (a kill can land in it)


@pytest.fixture
def composite_blend(bpy_clean, tmp_path):
    """A saved composite: a CG sphere over a plate sequence whose frames all differ (1 spp)."""
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    add_sphere(bpy, scene)
    add_sun(bpy, scene)
    grey_world(bpy, scene, 0.1)
    plates = {}
    for k in range(1, FRAMES + 1):
        plates[k] = (0.1 + 0.8 * np.random.default_rng(k).random((PH, PW, 3))).astype(np.float32)
        write_exr(tmp_path / "plate" / f"plate_{k:04d}.exr", plates[k])
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate" / "plate_0001.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path, plates


def plate_fraction(image, plate):
    """Fraction of pixels equal to ``plate`` (the composite leaves the plate exact off the CG)."""
    return float(np.all(np.abs(image[..., :3] - plate) <= 1e-6, axis=2).mean())


def test_killed_render_leaves_whole_frames_and_resumes(composite_blend, tmp_path):
    blend, plates = composite_blend
    out = tmp_path / "frames"
    log = open(tmp_path / "killed.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "platelight", "render", str(blend), "--out", str(out),
                             "--frames", f"1-{FRAMES}"], env=support.cli_env(), stdout=log, stderr=log)
    caught_writing = False
    deadline = time.monotonic() + 60
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            names = os.listdir(out) if out.is_dir() else []
            # the moment the third frame's file is created (whatever its name): two frames are
            # done and the third is being written; a writer that wrote into the final name
            # would leave it truncated here
            if len(names) >= 3:
                proc.send_signal(signal.SIGKILL)
                caught_writing = any(n.startswith(".composite_") for n in names)
                break
            time.sleep(0.0005)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        log.close()
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "killed.log").read_text()[-2000:]
    assert caught_writing     # the third frame was being written when the job died

    finals = sorted(out.glob("composite_*.exr"))     # what a compositor or editor would pick up
    numbers = [int(p.stem.split("_")[1]) for p in finals]
    assert 2 <= len(finals) < FRAMES and numbers == list(range(1, len(finals) + 1))
    for path, k in zip(finals, numbers):
        image = read_exr(path, "RGBA")               # complete and readable, and the right frame
        assert plate_fraction(image, plates[k]) > 0.6
    leftovers = [n for n in os.listdir(out) if not n.startswith("composite_")]
    assert all(n.startswith(".composite_") and ".partial-" in n for n in leftovers), leftovers
    print(f"killed after {len(finals)} frames; caught writing: {caught_writing}; leftovers {leftovers}")
    before = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in finals}

    again = support.run_cli("render", blend, "--out", out, "--frames", f"1-{FRAMES}", timeout=120)
    assert again.returncode == 0, again.stderr[-2000:]
    assert again.stdout.strip() == (f"PlateLight: rendered {FRAMES - len(finals)} frame(s), "
                                    f"kept {len(finals)} complete in {out}.")
    for name, stat in before.items():                 # completed frames were not redone
        assert ((out / name).stat().st_ino, (out / name).stat().st_mtime_ns) == stat
    assert sorted(os.listdir(out)) == [f"composite_{k:04d}.exr" for k in range(1, FRAMES + 1)]
    for k in range(1, FRAMES + 1):
        image = read_exr(out / f"composite_{k:04d}.exr", "RGBA")
        assert plate_fraction(image, plates[k]) > 0.6
        assert max(plate_fraction(image, plates[j]) for j in plates if j != k) < 0.01

    # a truncated frame under its final name (as Blender's own animation render leaves one) is
    # found, rendered again and replaced; the others are kept
    broken = out / "composite_0003.exr"
    data = broken.read_bytes()
    broken.write_bytes(data[: len(data) // 2])
    third = support.run_cli("render", blend, "--out", out, "--frames", f"1-{FRAMES}", timeout=120)
    assert third.returncode == 0, third.stderr[-2000:]
    assert "composite_0003.exr is incomplete" in third.stderr
    assert third.stdout.strip() == f"PlateLight: rendered 1 frame(s), kept {FRAMES - 1} complete in {out}."
    assert plate_fraction(read_exr(broken, "RGBA"), plates[3]) > 0.6


def test_part_and_png(composite_blend, tmp_path):
    blend, plates = composite_blend
    out = tmp_path / "png"
    result = support.run_cli("render", blend, "--out", out, "--frames", "1-4", "--part", "2/2",
                             "--format", "png", "--name", "shot", timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == f"PlateLight: rendered 2 frame(s) in {out}."
    assert sorted(os.listdir(out)) == ["shot_0003.png", "shot_0004.png"]


@pytest.mark.parametrize("args, message", [
    (["--frames", "9-3"], "ends before it starts"),
    (["--part", "3/2"], "does not exist"),
    (["--samples", "0"], "--samples must be between"),
    (["--name", ".hidden"], "plain file name prefix"),
])
def test_bad_arguments(tmp_path, args, message):
    blend = tmp_path / "scene.blend"
    blend.write_bytes(b"BLENDER-v500" + bytes(100))
    result = support.run_cli("render", blend, "--out", tmp_path / "o", *args)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_bad_files(tmp_path, bpy_clean):
    fake = tmp_path / "scene.blend"
    fake.write_text("hello")
    result = support.run_cli("render", fake, "--out", tmp_path / "o")
    assert result.returncode == 2 and "Not a .blend file" in result.stderr
    missing = support.run_cli("render", tmp_path / "missing.blend", "--out", tmp_path / "o")
    assert missing.returncode == 2 and "File not found" in missing.stderr
    (tmp_path / "file").write_text("x")
    bpy_clean.ops.wm.save_as_mainfile(filepath=str(tmp_path / "empty.blend"))   # no camera
    no_dir = support.run_cli("render", tmp_path / "empty.blend", "--out", tmp_path / "file")
    assert no_dir.returncode == 2 and "not a folder" in no_dir.stderr
    no_camera = support.run_cli("render", tmp_path / "empty.blend", "--out", tmp_path / "o")
    assert no_camera.returncode == 2 and "has no camera" in no_camera.stderr
    assert "Traceback" not in no_camera.stderr and not list((tmp_path / "o").iterdir())
