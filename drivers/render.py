"""`python -m platelight render scene.blend --out DIR [--frames 1-100] [--part 2/4]`: render a
.blend's frames (its composite, when the compositor is on) for a render farm, so that an
interrupted job leaves no half-written frame and a restarted one resumes.

The file logic (names, completeness, the plan) is the engine's, addon/render_files.py.
"""
from __future__ import annotations

import os
import sys

from ..addon.bake.frames import parse_frames, parse_part, split_frames
from ..addon.errors import PlateLightError
from ..addon.farm.progress import QUIET_HELP, Progress, blender_output
from ..addon.fileio import ensure_writable_folder, stale_temps, temp_path
from ..addon.render_files import check_prefix, commit, frame_path, plan
from .headless import check_blend, import_bpy, open_blend, stdout_to_stderr

FORMATS = {"exr": ("OPEN_EXR", ".exr"), "png": ("PNG", ".png"),
           "multilayer": ("OPEN_EXR", ".exr")}   # composite + named passes (addon/farm/multilayer.py)


def add_parser(sub):
    parser = sub.add_parser(
        "render", help="render a .blend's frames (the composite) for a farm: whole files only, resumable",
        description="Render the frames of a .blend (with its compositor: the PlateLight composite) "
                    "into DIR/NAME_0001.exr ... Each frame is rendered to a temporary name and "
                    "renamed when complete, so an interrupted job never leaves a half-written frame; "
                    "frames already complete are kept, so rerunning the same command resumes.")
    parser.add_argument("blend", help="the .blend file")
    parser.add_argument("--out", required=True, help="output folder (created if needed)")
    parser.add_argument("--frames", help="frames to render, e.g. 1-100 or 1,5,9-12 (default: the "
                        "scene's frame range)")
    parser.add_argument("--part", help="I/N: render only the I-th of N equal, contiguous chunks of "
                        "the frames (one per machine)")
    parser.add_argument("--name", default="composite", help="file name prefix (default: composite)")
    parser.add_argument("--format", choices=sorted(FORMATS), default="exr",
                        help="exr: float32 RGBA OpenEXR (default); png: 8-bit RGBA; multilayer: the "
                        "composite and named passes (CG, Shadows, Holdout, Depth, Normal, Cryptomatte)")
    parser.add_argument("--samples", type=int, help="Cycles samples per pixel (default: the scene's)")
    parser.add_argument("--force", action="store_true", help="render frames that are already complete too")
    parser.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    parser.set_defaults(func=run)


def run(args):
    blend = os.path.abspath(args.blend)
    check_blend(blend)
    frames = parse_frames(args.frames) if args.frames else None
    if args.samples is not None and not 1 <= args.samples <= 1 << 20:
        raise PlateLightError(f"--samples must be between 1 and {1 << 20}, not {args.samples}.")
    check_prefix(args.name)
    part = parse_part(args.part) if args.part else None
    if part:
        split_frames([], *part)      # says so now when the part does not exist
    folder = ensure_writable_folder(args.out)
    file_format, ext = FORMATS[args.format]

    bpy = import_bpy()
    with blender_output(args.quiet):
        open_blend(bpy, blend)
    scene = bpy.context.scene
    if scene.camera is None:
        raise PlateLightError(f"The scene {scene.name} has no camera to render from.")
    if frames is None:
        frames = list(range(scene.frame_start, scene.frame_end + 1))
    if part:
        frames = split_frames(frames, *part)
        if not frames:
            print("platelight render: this part has no frames (more parts than frames).")
            return 0

    render = scene.render
    settings = render.image_settings
    settings.file_format = file_format
    settings.color_mode = "RGBA"
    settings.color_depth = "32" if file_format == "OPEN_EXR" else "8"
    if file_format == "OPEN_EXR":
        settings.exr_codec = "ZIP"
    render.use_file_extension = True
    render.use_persistent_data = True        # scene sync once, not per frame
    if args.samples:
        scene.cycles.samples = args.samples

    with stdout_to_stderr():    # OpenEXR prints its complaints about broken files on stdout
        to_render, kept, broken = plan(folder, args.name, frames, ext, force=args.force)
    for frame in broken:
        print(f"platelight render: warning: {os.path.basename(frame_path(folder, args.name, frame, ext))} "
              "is incomplete (an interrupted earlier render); rendering it again.", file=sys.stderr)
    passes = None
    if args.format == "multilayer":
        from ..node_groups.passes import MultilayerPasses

        passes = MultilayerPasses(scene)
    progress = Progress("render", len(to_render))
    for frame in to_render:
        final = frame_path(folder, args.name, frame, ext)
        for old in stale_temps(final):
            os.unlink(old)
        tmp = temp_path(final)
        try:
            with blender_output(args.quiet):
                scene.frame_set(frame)
                render.filepath = tmp
                bpy.ops.render.render(write_still=True)
            if passes is not None:
                passes.join(frame, tmp)
            commit(tmp, final)
        except RuntimeError as exc:
            raise PlateLightError(f"Blender could not render frame {frame}: "
                                  f"{str(exc).strip().splitlines()[-1]}") from None
        except OSError as exc:
            raise PlateLightError(f"Cannot write {final}: {exc.strerror}.") from None
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        progress.step(f"frame {frame}")
    if passes is not None:
        passes.close()
    summary = f"PlateLight: rendered {len(to_render)} frame(s)"
    if kept:
        summary += f", kept {len(kept)} complete"
    print(summary + f" in {folder}.")
    return 0
