"""`python -m platelight bake scene.blend [--frames 10-20] [--part 2/4]`: bake a .blend's probes
without opening Blender's window. bpy runs in this process (the project's environment has it);
split a long range across machines with --part I/N (each writes only its own frames' files).
A scene composited with baked shadows (setup_composite's BAKED method) gets its shot's shadows
baked too (by part 1 only: they serve every frame)."""
from __future__ import annotations

import importlib
import os
import sys

from ..addon.bake.frames import parse_frames, parse_part, split_frames
from ..addon.errors import PlateLightError
from ..addon.farm.progress import QUIET_HELP, Progress, blender_output
from .headless import check_blend, import_bpy, open_blend, stdout_to_stderr


def add_parser(sub):
    parser = sub.add_parser(
        "bake", help="bake the per-object probes of a .blend (headless Blender)",
        description="Render every PlateLight object's surroundings from its centre and bake its "
                    "maps into the scene's Maps Folder (next to the .blend).")
    parser.add_argument("blend", help="the .blend file")
    parser.add_argument("--frames", help="frames to bake, e.g. 10-20 or 1,5,9-12 (per-frame maps "
                        "diffuse_0010.exr ...); default: the file's current frame, single-frame maps")
    parser.add_argument("--part", help="I/N: bake only the I-th of N equal, contiguous chunks of "
                        "--frames (one per machine)")
    parser.add_argument("--objects", help="comma-separated object names (default: every PlateLight object)")
    parser.add_argument("--force", action="store_true", help="re-render probes whose inputs did not change")
    parser.add_argument("--no-cull", action="store_true", help="bake objects that are off screen too")
    parser.add_argument("--samples", type=int, help="Cycles samples per probe (default: the scene's)")
    parser.add_argument("--height", type=int, help="probe height in pixels (default: the scene's)")
    parser.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    parser.add_argument("--save", action="store_true",
                        help="save the .blend afterwards (records each object's probe folder and status)")
    parser.set_defaults(func=run)


def run(args):
    blend = os.path.abspath(args.blend)
    check_blend(blend)
    frames = parse_frames(args.frames) if args.frames else None
    if args.part:
        if frames is None:
            raise PlateLightError("--part needs --frames (the range to split).")
        frames = split_frames(frames, *parse_part(args.part))
        if not frames:
            print("platelight bake: this part has no frames (more parts than frames).")
            return 0
    for name in ("samples", "height"):
        value = getattr(args, name)
        if value is not None and not 1 <= value <= 65536:
            raise PlateLightError(f"--{name} must be between 1 and 65536, not {value}.")

    bpy = import_bpy()
    root = __package__.rsplit(".", 1)[0]
    package = importlib.import_module(root)
    with blender_output(args.quiet):
        open_blend(bpy, blend)
    registered = hasattr(bpy.types.Object, "platelight") and hasattr(bpy.ops.platelight, "bake_probes")
    if not registered:
        package.register()
    bake = importlib.import_module(f"{root}.operators.bake.job")
    context = bpy.context
    scene = context.scene
    if args.samples:
        scene.platelight.probe_samples = args.samples
    if args.height:
        scene.platelight.probe_height = args.height
    if args.objects:
        names = [n.strip() for n in args.objects.split(",") if n.strip()]
        missing = [n for n in names if n not in scene.objects]
        if missing:
            raise PlateLightError(f"No object named {', '.join(missing)} in the scene {scene.name}.")
        objects = [scene.objects[n] for n in names]
    else:
        objects = bake.target_objects(context, all_objects=True)

    steps = Progress("bake", 0, unit="probe")

    def progress(done, total):
        steps.total, steps.stream = total, log
        steps.step(f"probe {done}")

    shadows = importlib.import_module(f"{root}.operators.baked_shadows")
    wants_shadows = shadows.uses_baked_shadows(scene)
    job = baked = None
    if objects or not wants_shadows:         # no PlateLight object: an error unless shadows are asked
        with blender_output(args.quiet) as log:    # Blender's render log; stdout keeps only the summary
            job = bake.bake_probes(context, objects, frames or [scene.frame_current], static=frames is None,
                                   use_cache=not args.force, cull=not args.no_cull, progress=progress)
    if wants_shadows and (not args.part or parse_part(args.part)[0] == 1):
        with blender_output(args.quiet):
            baked = shadows.bake_shadows(context, use_cache=not args.force)
    for warning in (job.warnings if job else []) + (baked["warnings"] if baked else []):
        print(f"platelight bake: warning: {warning}", file=sys.stderr)
    if job:
        print(job.summary())
    if baked:
        print(f"The baked shadows in {baked['folder']} are up to date." if baked["reused"] else
              f"Shadows baked in {baked['seconds']:.1f} s into {baked['folder']}.")
    if args.save:
        with stdout_to_stderr():
            bpy.ops.wm.save_mainfile()
    return 0
