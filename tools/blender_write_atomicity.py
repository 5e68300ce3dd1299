"""Experiment: does Blender 5.0 write its render output atomically? (docs/compositing.md)

A child process imports bpy and renders a 40-frame animation (`render(animation=True)`, 1 spp,
SIZE×SIZE float32 ZIP EXR) into a folder; this process kills it with SIGKILL, either at a random
moment (`random`) or the moment a chosen frame's file appears (`aimed`: while Blender writes it),
then reads every file in the folder back. Any unreadable file under a frame's final name means
the write is not atomic.

    .venv/bin/python tools/blender_write_atomicity.py aimed 5
    .venv/bin/python tools/blender_write_atomicity.py random 5 [--size 1024]
"""
from __future__ import annotations

import argparse
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[1]


def child(out, size):
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="platelight-atomicity-")
    import bpy

    bpy.ops.wm.read_homefile(use_factory_startup=True)     # the default cube, camera and light
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, 40
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "32", "ZIP"
    scene.render.filepath = os.path.join(out, "frame_####")
    bpy.ops.render.render(animation=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("aimed", "random"))
    parser.add_argument("trials", type=int)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return child(args.child, args.size)
    sys.path.insert(0, str(REPO / "tests"))
    import support  # noqa: F401  (platelight = this checkout)
    from platelight.addon.errors import PlateLightError
    from platelight.addon.exr_io import read_exr

    rng = random.Random(args.seed)
    broken_trials = 0
    for trial in range(args.trials):
        out = pathlib.Path(tempfile.mkdtemp(prefix="platelight-atomicity-out-"))
        proc = subprocess.Popen([sys.executable, __file__, args.mode, "1", "--size", str(args.size),
                                 "--child", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t0 = time.monotonic()
        if args.mode == "random":
            time.sleep(rng.uniform(3, 10))
        else:
            target = out / f"frame_{rng.randint(1, 3):04d}.exr"
            while not target.exists() and proc.poll() is None:
                time.sleep(0.0005)
            time.sleep(rng.uniform(0, 0.05))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        files = sorted(out.iterdir())
        bad = []
        for path in files:
            try:
                read_exr(path, "RGBA")
            except PlateLightError:
                bad.append(f"{path.name} ({path.stat().st_size} bytes)")
        broken_trials += bool(bad)
        print(f"{args.mode} {trial}: killed after {time.monotonic() - t0:.2f} s, {len(files)} file(s), "
              f"unreadable: {', '.join(bad) or 'none'}", flush=True)
        shutil.rmtree(out, ignore_errors=True)
    print(f"{broken_trials}/{args.trials} kills left a truncated frame under its final name")


if __name__ == "__main__":
    main()
