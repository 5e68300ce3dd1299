"""`python -m platelight farm-job`: a 4-frame job exported, checked and run by the real `openjd`
(with no argument but the template) from a copy of the bundle whose original files are gone,
giving frames identical to a direct `bake` + `render`; a job killed (SIGKILL, the whole process
group) mid-render resumes without redoing complete work; bad input gets one sentence each; the
Export Farm Job operator writes the same bundle and leaves the user's scene as it was."""
from __future__ import annotations

import hashlib
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

import support
from farm_scene import FRAMES, make_shot
from platelight.addon.exr_io import read_exr

OPENJD = pathlib.Path(sys.executable).parent / "openjd"


@pytest.fixture
def shot(bpy_clean, tmp_path):
    return make_shot(bpy_clean, tmp_path)


def openjd(*args, timeout=600, **kw):
    return subprocess.run([str(OPENJD), *map(str, args)], env=support.cli_env(), capture_output=True,
                          text=True, timeout=timeout, **kw)


def digest(path):
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def frames_of(folder):
    return {k: read_exr(folder / f"composite_{k:04d}.exr", "RGBA") for k in range(1, FRAMES + 1)}


def test_openjd_runs_the_bundle_elsewhere_and_matches_a_direct_render(shot, tmp_path):
    blend, plates = shot
    inputs = sorted((tmp_path / "plate").iterdir()) + [tmp_path / "probe" / "probe.exr", blend]
    before = {p: digest(p) for p in inputs}
    made = support.run_cli("farm-job", blend, "--frames", f"1-{FRAMES}", "--chunk", "2",
                           "--out", tmp_path / "job")
    assert made.returncode == 0, made.stderr[-2000:]
    assert made.stdout.startswith(f"PlateLight: farm job in {tmp_path / 'job'}: a bake task, then 2 render task(s)")
    assert openjd("check", tmp_path / "job" / "template.yaml").returncode == 0
    template = (tmp_path / "job" / "template.yaml").read_text()
    assert str(tmp_path) not in template         # nothing points back at this machine's files

    # another "machine": the bundle moved, the original shot, plate and probe gone
    moved = tmp_path / "elsewhere" / "job"
    moved.parent.mkdir()
    shutil.move(tmp_path / "job", moved)
    hidden = tmp_path / "hidden"
    hidden.mkdir()
    for name in ("plate", "probe", "shot"):
        shutil.move(tmp_path / name, hidden / name)
    run = openjd("run", moved / "template.yaml")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "PlateLight: baked 4 probe(s)." in run.stdout
    assert "Saved:" not in run.stdout           # --quiet: no Cycles per-frame log
    assert "platelight render: frame 4 done" in run.stdout
    assert sorted(os.listdir(moved / "output")) == [f"composite_{k:04d}.exr" for k in range(1, FRAMES + 1)]
    for name in ("plate", "probe", "shot"):
        shutil.move(hidden / name, tmp_path / name)
    assert {p: digest(p) for p in inputs} == before        # the user's files were not touched

    # the same frames straight from the CLI on the original scene
    assert support.run_cli("bake", blend, "--frames", f"1-{FRAMES}").returncode == 0
    direct = support.run_cli("render", blend, "--frames", f"1-{FRAMES}", "--out", tmp_path / "direct")
    assert direct.returncode == 0, direct.stderr[-2000:]
    farm, local = frames_of(moved / "output"), frames_of(tmp_path / "direct")
    for k in range(1, FRAMES + 1):
        assert np.array_equal(farm[k], local[k]), k
        on_plate = np.all(np.abs(farm[k][..., :3] - plates[k]) <= 1e-6, axis=2).mean()
        assert 0.3 < on_plate < 0.99, on_plate    # the plate, with CG and its shadow on it


def test_killed_job_resumes_without_redoing_work(shot, tmp_path):
    blend, _ = shot
    assert support.run_cli("farm-job", blend, "--frames", f"1-{FRAMES}", "--out", tmp_path / "job").returncode == 0
    out = tmp_path / "job" / "output"
    log = open(tmp_path / "killed.log", "w")
    proc = subprocess.Popen([str(OPENJD), "run", str(tmp_path / "job" / "template.yaml")], env=support.cli_env(),
                            stdout=log, stderr=log, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline:
            if out.is_dir() and len([n for n in os.listdir(out) if not n.startswith(".")]) >= 2:
                os.killpg(proc.pid, signal.SIGKILL)      # openjd and the render it runs
                break
            time.sleep(0.002)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        log.close()
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "killed.log").read_text()[-3000:]
    done = sorted(n for n in os.listdir(out) if not n.startswith("."))
    assert 2 <= len(done) < FRAMES, done
    for name in done:
        read_exr(out / name, "RGBA")                     # whole files only under final names
    stamps = {n: (out / n).stat().st_mtime_ns for n in done}

    again = openjd("run", tmp_path / "job" / "template.yaml")
    assert again.returncode == 0, again.stdout[-3000:]
    assert f"PlateLight: reused {FRAMES} unchanged." in again.stdout      # the bake was complete
    # one frame per task: the tasks of the complete frames render nothing
    assert again.stdout.count("PlateLight: rendered 0 frame(s), kept 1 complete") == len(done)
    assert {n: (out / n).stat().st_mtime_ns for n in done} == stamps
    assert sorted(os.listdir(out)) == [f"composite_{k:04d}.exr" for k in range(1, FRAMES + 1)]


def test_killed_bake_leaves_whole_maps_and_resumes(shot, tmp_path):
    """The bake writes each map by rename and the frame's record after its maps: killed while
    baking, it leaves no half-written map, and a rerun bakes only the frames without a record."""
    blend, _ = shot
    maps = tmp_path / "shot" / "platelight_maps" / "Ball"
    args = [sys.executable, "-m", "platelight", "bake", str(blend), "--frames", f"1-{FRAMES}",
            "--height", "256", "--samples", "4"]     # slow enough that the kill lands mid-bake
    log = open(tmp_path / "bake.log", "w")
    proc = subprocess.Popen(args, env=support.cli_env(), stdout=log, stderr=log)
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline:
            if (maps / "bake_0001.json").exists():
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.002)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        log.close()
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "bake.log").read_text()[-3000:]
    records = sorted(maps.glob("bake_*.json"))
    assert 1 <= len(records) < FRAMES
    for path in maps.iterdir():
        if path.suffix == ".exr" and not path.name.startswith("."):
            read_exr(path, "RGB")                       # every map under its final name is whole
    for record in records:
        frame = record.stem.split("_")[1]
        assert all((maps / f"{m}_{frame}.exr").is_file() for m in ("diffuse", "glossy1", "glossy2", "specular"))
    again = support.run_cli(*args[3:], "--quiet")
    assert again.returncode == 0, again.stderr[-2000:]
    # --quiet: Blender's log is gone, PlateLight's progress is there, one line per probe baked
    lines = again.stderr.strip().splitlines()
    assert all(line.startswith("platelight bake: probe ") for line in lines), lines
    assert len(lines) == FRAMES and lines[-1].startswith(f"platelight bake: probe {FRAMES} done ({FRAMES}/{FRAMES}, 0 left)")
    assert again.stdout.strip() == (f"PlateLight: baked {FRAMES - len(records)} probe(s); "
                                    f"reused {len(records)} unchanged."), again.stdout


@pytest.mark.parametrize("case, message", [
    ("unsaved", "File not found"),
    ("outside", "lie outside the scene's frame range 1-4"),
    ("unwritable", "Cannot create output folder"),
    ("plate", "The plate has no file for frame(s) 3"),
    ("probe", "The world probe"),
    ("chunk", "--chunk must be at least 1 frame, not 0"),
    ("not empty", "holds other files"),
])
def test_bad_input_gets_one_sentence(shot, tmp_path, case, message):
    blend, _ = shot
    args = {"frames": "1-4", "chunk": "2", "out": tmp_path / "job"}
    if case == "unsaved":
        blend = tmp_path / "never_saved.blend"
    elif case == "outside":
        args["frames"] = "3-9"
    elif case == "unwritable":
        (tmp_path / "a_file").write_text("x")
        args["out"] = tmp_path / "a_file" / "job"
    elif case == "plate":
        (tmp_path / "plate" / "plate_0003.exr").unlink()
    elif case == "probe":
        (tmp_path / "probe" / "probe.exr").unlink()
    elif case == "chunk":
        args["chunk"] = "0"
    elif case == "not empty":
        (tmp_path / "job").mkdir()
        (tmp_path / "job" / "notes.txt").write_text("mine")
    result = support.run_cli("farm-job", blend, *[x for k, v in args.items() for x in (f"--{k}", v)])
    assert result.returncode == 2, result.stdout + result.stderr
    assert message in result.stderr and "Traceback" not in result.stderr
    assert result.stderr.startswith("platelight farm-job: error: ")
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    job = tmp_path / "job"
    assert not (job / "template.yaml").exists() and not (job / "scene").exists()


def test_export_operator(shot, bpy_module, tmp_path):
    bpy = bpy_module
    blend, _ = shot
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    plate = bpy.data.images["PlateLight Plate"]
    paths = (plate.filepath, bpy.context.scene.platelight.world_probe)
    result = bpy.ops.platelight.export_farm_job(directory=str(tmp_path / "job") + "/", chunk=3, format="multilayer")
    assert result == {"FINISHED"}
    assert (plate.filepath, bpy.context.scene.platelight.world_probe) == paths      # restored
    assert not bpy.data.is_dirty or bpy.data.filepath == str(blend)
    template = yaml.safe_load((tmp_path / "job" / "template.yaml").read_text())
    defaults = {p["name"]: p["default"] for p in template["parameterDefinitions"]}
    assert defaults["Frames"] == "1-4" and defaults["ChunkSize"] == 3 and defaults["OutputFormat"] == "multilayer"
    assert (tmp_path / "job" / "scene" / "scene.blend").is_file()
    assert openjd("check", tmp_path / "job" / "template.yaml").returncode == 0
    # the bundle's copy reads its plate and probe beside it, by relative paths
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "job" / "scene" / "scene.blend"))
    copy = bpy.data.images["PlateLight Plate"]
    assert copy.filepath.startswith("//external/") and os.path.isfile(bpy.path.abspath(copy.filepath))
    assert bpy.context.scene.platelight.world_probe.startswith("//external/")

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    bpy.ops.object.camera_add()
    bpy.context.scene.camera = bpy.context.object
    assert not bpy.ops.platelight.export_farm_job.poll()        # unsaved: "Save the .blend file first"
