"""`python -m platelight farm-job SCENE.blend --frames A-B [--chunk N] --out JOBDIR`: write an Open
Job Description bundle (addon/farm/jobs.py) that bakes and renders the scene on a render farm.
Argument checks come first (no Blender needed); the scene is then opened headless and exported
by the same code as the *Export Farm Job* operator (operators/farm_job.py)."""
from __future__ import annotations

import importlib
import os

from ..addon.bake.frames import parse_frames
from ..addon.errors import PlateLightError
from ..addon.farm import jobs
from ..addon.farm.progress import blender_output
from ..addon.fileio import ensure_writable_folder
from ..addon.render_files import check_prefix
from .headless import check_blend, import_bpy, open_blend


def add_parser(sub):
    parser = sub.add_parser(
        "farm-job", help="write an Open Job Description job bundle (bake, then render) for a farm",
        description="Write an Open Job Description job bundle in AWS Deadline Cloud's layout "
                    "(JOBDIR/template.yaml, parameter_values.yaml, asset_references.yaml and the scene "
                    "with its files under JOBDIR/scene): a bake step, then a render step of frame "
                    "chunks. `openjd run JOBDIR/template.yaml` runs the whole job.")
    parser.add_argument("blend", help="the saved .blend file")
    parser.add_argument("--frames", required=True, help="frames, e.g. 1-100 (inside the scene's range)")
    parser.add_argument("--chunk", type=int, default=1, help="frames per render task (default: 1)")
    parser.add_argument("--out", required=True, help="the job folder (new, empty, or an earlier job)")
    parser.add_argument("--format", choices=jobs.FORMATS, default="exr",
                        help="frames written by the job: exr (default), multilayer (with passes), png")
    parser.add_argument("--name", default="composite", help="file name prefix of the frames")
    parser.add_argument("--python", help="the interpreter farm machines run `-m platelight` with "
                        "(default: this one)")
    parser.set_defaults(func=run)


def run(args):
    if args.chunk < 1:
        raise PlateLightError(f"--chunk must be at least 1 frame, not {args.chunk}.")
    blend = os.path.abspath(args.blend)
    if not os.path.exists(blend):
        raise PlateLightError(f"File not found: {blend} (save the scene there first).")
    check_blend(blend)
    frames = parse_frames(args.frames)
    check_prefix(args.name)
    ensure_writable_folder(args.out)

    bpy = import_bpy()
    root = __package__.rsplit(".", 1)[0]
    with blender_output(quiet=True):      # Blender's log says nothing a job export needs
        open_blend(bpy, blend)
    if not hasattr(bpy.types.Scene, "platelight"):
        importlib.import_module(root).register()
    farm_job = importlib.import_module(f"{root}.operators.farm_job")
    with blender_output(quiet=True):
        job = farm_job.export_farm_job(bpy.context, args.out, frames, chunk=args.chunk, fmt=args.format,
                                       prefix=args.name, python=args.python)
    folder = os.path.abspath(args.out)
    tasks = len(jobs.chunks(job.frames, job.chunk))
    steps = "a bake task, then " if job.bake else "no PlateLight objects to bake; "
    print(f"PlateLight: farm job in {folder}: {steps}{tasks} render task(s) of up to {job.chunk} "
          f"frame(s) (frames {jobs.range_expression(job.frames)}). Run it here with: "
          f"openjd run {os.path.join(folder, jobs.TEMPLATE)}")
    return 0
