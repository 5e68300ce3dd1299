"""Footage on disk: movie files and numbered image sequences (bpy-free).

A numbered file (``plate_0001.exr``) belongs to the sequence of files with the same prefix and
extension; the plate operator (operators/plate.py) and grain matching read frames through these."""
from __future__ import annotations

import os
import re

from .errors import PlateLightError

MOVIE_EXTENSIONS = {".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".ogv"}
# A numbered file of an image sequence: prefix, frame digits, extension.
NUMBERED_FILE = re.compile(r"^(.*?)(\d+)(\.[A-Za-z0-9]+)$")


def scan_sequence(path):
    """(first, last, count) of the numbered sequence ``path`` belongs to; raises PlateLightError for
    missing frames. A file without a number is a single still (1, 1, 1)."""
    folder, name = os.path.split(path)
    match = NUMBERED_FILE.match(name)
    if not match:
        return 1, 1, 1
    prefix, digits, ext = match.groups()
    pattern = re.compile(re.escape(prefix) + r"(\d+)" + re.escape(ext) + "$")
    numbers = sorted(int(m.group(1)) for m in map(pattern.match, os.listdir(folder or ".")) if m)
    missing = sorted(set(range(numbers[0], numbers[-1] + 1)) - set(numbers))
    if missing:
        shown = ", ".join(map(str, missing[:8])) + (" ..." if len(missing) > 8 else "")
        raise PlateLightError(f"The plate sequence {prefix}#{ext} has {len(missing)} missing frame(s) "
                         f"({shown}); render or copy them before using it as a plate.")
    return numbers[0], numbers[-1], len(numbers)


def sequence_frame_path(path, frame):
    """The file of frame ``frame`` in the numbered sequence ``path`` belongs to (``path`` itself
    for a file without a number)."""
    folder, name = os.path.split(path)
    match = NUMBERED_FILE.match(name)
    if not match:
        return path
    prefix, digits, ext = match.groups()
    return os.path.join(folder, f"{prefix}{frame:0{len(digits)}d}{ext}")


def frame_rate_pair(fps):
    """Blender's (fps, fps_base) for a frame rate: integer rates exactly, NTSC rates (23.976,
    29.97, 59.94: N/1.001) as (N, 1.001) like Blender's own presets, anything else (N, N/fps).
    Movie containers store rates as float32 (23.97599983), so they are snapped to these."""
    whole = round(fps)
    if whole >= 1 and abs(fps - whole) < 1e-3:
        return whole, 1.0
    ntsc = round(fps * 1.001)
    if ntsc >= 1 and abs(fps * 1.001 - ntsc) < 1e-3:
        return ntsc, 1.001
    whole = max(1, whole)
    return whole, whole / fps
