"""`python -m platelight render scene.blend --out DIR [--frames 1-100] [--part 2/4]`: render a
.blend's frames (its composite, when the compositor is on) for a render farm, so that an
interrupted job leaves no half-written frame and a restarted one resumes.

Blender 5.0 does not write its output files atomically: `render(animation=True)` and
`render(write_still=True)` open the final name with O_TRUNC and write into it (seen with strace), so
a job killed while writing leaves a truncated file under the final name (2 of 3 kills aimed at the
write did, docs/compositing.md), and Blender's own resume (Overwrite off, Placeholders on) then
skips that broken file forever. Here every frame is rendered to a hidden temporary name in the
same folder (`.NAME_0007.partial-PID.exr`), checked, flushed to disk and renamed into place; a
frame whose final file exists and is complete is kept, so a rerun renders only what is missing.

The file logic (names, completeness, the plan) is bpy-free; only ``run`` imports bpy.
"""
from __future__ import annotations

import glob
import os
import sys

from .errors import PlateLightError

FORMATS = {"exr": ("OPEN_EXR", ".exr"), "png": ("PNG", ".png"),
           "multilayer": ("OPEN_EXR", ".exr")}   # composite + named passes (addon/farm/multilayer.py)
PARTIAL = ".partial-"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


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
    parser.add_argument("--quiet", action="store_true", help="farm logs: drop Blender's own render log "
                        "(Cycles' 'Saved:' lines); keep PlateLight's progress lines")
    parser.set_defaults(func=run)


# --- bpy-free file logic -------------------------------------------------------------------

def frame_path(folder, name, frame, ext):
    return os.path.join(folder, f"{name}_{frame:04d}{ext}")


def temp_path(final):
    """A hidden name in the final file's folder (so the rename never crosses file systems and a
    glob of NAME_*.EXT never sees it), unique to this process."""
    folder, base = os.path.split(final)
    stem, ext = os.path.splitext(base)
    return os.path.join(folder, f".{stem}{PARTIAL}{os.getpid()}{ext}")


def stale_temps(final):
    """Temporary files left for this frame by earlier, interrupted jobs."""
    folder, base = os.path.split(final)
    stem, ext = os.path.splitext(base)
    return glob.glob(os.path.join(glob.escape(folder), f".{glob.escape(stem)}{PARTIAL}*{ext}"))


def is_complete(path):
    """True when ``path`` is a whole, readable image: an EXR that decodes, a PNG that ends with
    its IEND chunk. Files this command writes are complete by construction (rename); this also
    catches truncated frames left by Blender's own (non-atomic) animation render."""
    if not os.path.isfile(path):
        return False
    if path.endswith(".exr"):
        from .exr_io import read_exr

        try:
            read_exr(path, "RGBA")
        except PlateLightError:
            return False
        return True
    with open(path, "rb") as fh:
        fh.seek(0, os.SEEK_END)
        if fh.tell() < len(PNG_END) + 8:
            return False
        fh.seek(-len(PNG_END), os.SEEK_END)
        return fh.read() == PNG_END


def plan(folder, name, frames, ext, force=False):
    """(to_render, kept, broken): frames to render, frames already complete, and frames whose
    final file exists but is not complete (they are rendered again and replaced)."""
    to_render, kept, broken = [], [], []
    for frame in frames:
        final = frame_path(folder, name, frame, ext)
        if not force and is_complete(final):
            kept.append(frame)
            continue
        if os.path.exists(final) and not is_complete(final):
            broken.append(frame)
        to_render.append(frame)
    return to_render, kept, broken


def _fsync(path, directory=False):
    fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def commit(tmp, final):
    """Make ``tmp`` (complete) the frame ``final``: flushed to disk first, then one rename."""
    if not is_complete(tmp):
        raise PlateLightError(f"Blender did not write a complete image for {os.path.basename(final)}; "
                              "see the render log above.")
    _fsync(tmp)
    os.replace(tmp, final)
    _fsync(os.path.dirname(final) or ".", directory=True)


# --- the command ---------------------------------------------------------------------------

def run(args):
    from .bake.cli_bake import _check_blend, _import_bpy, _parse_part, _stdout_to_stderr
    from .bake.frames import parse_frames, split_frames
    from .fileio import ensure_writable_folder

    blend = os.path.abspath(args.blend)
    _check_blend(blend)
    frames = parse_frames(args.frames) if args.frames else None
    if args.samples is not None and not 1 <= args.samples <= 1 << 20:
        raise PlateLightError(f"--samples must be between 1 and {1 << 20}, not {args.samples}.")
    if not args.name or os.sep in args.name or args.name.startswith("."):
        raise PlateLightError(f"--name must be a plain file name prefix, not {args.name!r}.")
    part = _parse_part(args.part) if args.part else None
    if part:
        split_frames([], *part)      # says so now when the part does not exist
    folder = ensure_writable_folder(args.out)
    file_format, ext = FORMATS[args.format]

    bpy = _import_bpy()
    try:
        with _stdout_to_stderr():
            bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    except RuntimeError as exc:
        raise PlateLightError(f"Blender cannot open {blend}: {str(exc).strip().splitlines()[-1]}") from None
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

    with _stdout_to_stderr():    # OpenEXR prints its complaints about broken files on stdout
        to_render, kept, broken = plan(folder, args.name, frames, ext, force=args.force)
    for frame in broken:
        print(f"platelight render: warning: {os.path.basename(frame_path(folder, args.name, frame, ext))} "
              "is incomplete (an interrupted earlier render); rendering it again.", file=sys.stderr)
    from .farm.progress import Progress, blender_output

    passes = None
    if args.format == "multilayer":
        import importlib

        passes = importlib.import_module(__package__.rsplit(".addon", 1)[0] + ".node_groups.passes")
        passes = passes.MultilayerPasses(scene)
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
