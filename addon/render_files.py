"""Whole-file frame output for farm rendering (`python -m platelight render`, drivers/render.py):
frame names, hidden temporary names beside the final one, completeness checks, the resume plan
and the flush-then-rename commit.

Blender 5.0 does not write its output files atomically: `render(animation=True)` and
`render(write_still=True)` open the final name with O_TRUNC and write into it (seen with strace), so
a job killed while writing leaves a truncated file under the final name (2 of 3 kills aimed at the
write did, docs/compositing.md), and Blender's own resume (Overwrite off, Placeholders on) then
skips that broken file forever. Hence a hidden temporary name in the same folder
(`.NAME_0007.partial-PID.exr`, fileio.temp_path), checked, flushed to disk and renamed into place."""
from __future__ import annotations

import os

from .errors import PlateLightError
from .fileio import replace_file

PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def frame_path(folder, name, frame, ext):
    return os.path.join(folder, f"{name}_{frame:04d}{ext}")


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


def commit(tmp, final):
    """Make ``tmp`` (complete) the frame ``final``: flushed to disk first, then one rename."""
    if not is_complete(tmp):
        raise PlateLightError(f"Blender did not write a complete image for {os.path.basename(final)}; "
                              "see the render log above.")
    replace_file(tmp, final, durable=True)


def check_prefix(name: str) -> None:
    """The frames' file name prefix: plain (no folder, not hidden: hidden names are temporaries)."""
    if not name or os.sep in name or name.startswith("."):
        raise PlateLightError(f"The output name must be a plain file name prefix, not {name!r}.")
