"""`python -m platelight bake scene.blend --frames ...` (bpy in a subprocess), split across
"machines" with --part, and its bad input."""
from __future__ import annotations

import json

import pytest

import support
from bake_scenes import add_sphere, maps_folder, new_scene


@pytest.fixture
def saved_scene(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.2, 0.3, 0.4), save=False, height=16, samples=2)
    add_sphere(bpy, "Ball", (0, 0, 0))
    mover = add_sphere(bpy, "Mover", (2, 0, 0), color=(0.9, 0.1, 0.1))
    mover.keyframe_insert("location", frame=1)
    mover.location = (2, 2, 0)
    mover.keyframe_insert("location", frame=4)
    scene.frame_set(1)
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_frame_range_split_over_two_machines(saved_scene, tmp_path, bpy_module):
    first = support.run_cli("bake", saved_scene, "--frames", "1-4", "--part", "1/2")
    assert first.returncode == 0, first.stderr
    # frames 1-2, two objects; stdout holds only the summary (the render log goes to stderr)
    assert first.stdout.strip() == "PlateLight: baked 4 probe(s)."
    second = support.run_cli("bake", saved_scene, "--frames", "1-4", "--part", "2/2", "--save")
    assert second.returncode == 0, second.stderr
    for name in ("Ball", "Mover"):
        folder = maps_folder(tmp_path, name)
        for frame in (1, 2, 3, 4):
            assert (folder / f"diffuse_{frame:04d}.exr").is_file()
            record = json.loads((folder / f"bake_{frame:04d}.json").read_text())
            assert record["scene_frame"] == frame and record["object"] == name
    # --save recorded where each object's maps are, relative to the .blend.
    bpy_module.ops.wm.open_mainfile(filepath=str(saved_scene))
    ball = bpy_module.data.objects["Ball"].platelight
    assert ball.probe_dir == "//platelight_maps/Ball/" and ball.probe_status == "baked (frames 3-4)"
    # Nothing changed: a rerun of the whole range renders nothing.
    again = support.run_cli("bake", saved_scene, "--frames", "1-4")
    assert again.returncode == 0, again.stderr
    assert "reused 8 unchanged" in again.stdout and "baked" not in again.stdout
    assert again.stdout.strip().splitlines() == ["PlateLight: reused 8 unchanged."]


def test_single_frame_and_objects(saved_scene, tmp_path):
    result = support.run_cli("bake", saved_scene, "--objects", "Ball", "--no-cull")
    assert result.returncode == 0, result.stderr
    assert (maps_folder(tmp_path, "Ball") / "diffuse.exr").is_file()
    assert not maps_folder(tmp_path, "Mover").exists()


@pytest.mark.parametrize("args, message", [
    (["--frames", "9-3"], "ends before it starts"),
    (["--part", "1/2"], "--part needs --frames"),
    (["--frames", "1-4", "--part", "5/2"], "does not exist"),
    (["--objects", "Nobody"], "No object named Nobody"),
    (["--samples", "0"], "between 1 and 65536"),
])
def test_bad_arguments(saved_scene, args, message):
    result = support.run_cli("bake", saved_scene, *args)
    assert result.returncode == 2
    assert message in result.stderr and "Traceback" not in result.stderr


def test_not_a_blend(tmp_path):
    fake = tmp_path / "scene.blend"
    fake.write_text("hello")
    result = support.run_cli("bake", fake)
    assert result.returncode == 2 and "Not a .blend file" in result.stderr
    missing = support.run_cli("bake", tmp_path / "missing.blend")
    assert missing.returncode == 2 and "File not found" in missing.stderr


def test_headless_runs_leave_no_temporary_folders(tmp_path):
    """Each run's Blender profile and Blender's own session folder are removed when it ends, on
    error too (none piles up as platelight-cli-profile-* in the temp folder)."""
    import os
    import subprocess
    import sys

    own_tmp = tmp_path / "tmp"
    own_tmp.mkdir()
    broken = tmp_path / "broken.blend"
    broken.write_bytes(b"BLENDER-v300 not really a .blend")
    env = dict(support.cli_env(), TMPDIR=str(own_tmp))
    proc = subprocess.run([sys.executable, "-m", "platelight", "bake", str(broken)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "Blender cannot open" in proc.stderr, proc.stderr
    assert os.listdir(own_tmp) == []
