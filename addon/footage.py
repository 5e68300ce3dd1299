"""Footage on disk (bpy-free): movie files, folders of frames and numbered image sequences, and
reading their frames (OpenCV; EXR through exr_io).

A numbered file (``plate_0001.exr``) belongs to the sequence of files with the same prefix and
extension; the plate operator (operators/plate.py), grain matching and tracking read through here."""
from __future__ import annotations

import os
import re
from typing import Iterator

import numpy as np

from .errors import PlateLightError

# FFmpeg's own log lines would follow our one-sentence errors on stderr (read when first used).
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr", ".webp")
MOVIE_EXTENSIONS = (".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".ogv")
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


def list_frames(source: str | os.PathLike) -> tuple[str, list[str]]:
    """("folder", sorted image paths) or ("video", [path])."""
    source = os.fspath(source)
    if not os.path.exists(source):
        raise PlateLightError(f"Frames not found: {source}")
    if os.path.isdir(source):
        files = sorted(os.path.join(source, f) for f in os.listdir(source)
                       if f.lower().endswith(IMAGE_EXTENSIONS) and not f.startswith("."))
        if not files:
            raise PlateLightError(f"The folder holds no images ({', '.join(IMAGE_EXTENSIONS)}): {source}")
        return "folder", files
    return "video", [source]


def read_image(path: str) -> np.ndarray:
    import cv2

    img = cv2.imread(path, cv2.IMREAD_UNCHANGED) if not path.lower().endswith(".exr") else None
    if img is None and path.lower().endswith(".exr"):
        from .exr_io import read_exr
        img = read_exr(path)[..., ::-1]
    if img is None:
        raise PlateLightError(f"Cannot read the image (not an image file, or damaged): {path}")
    return img


def iter_frames(source: str | os.PathLike) -> Iterator[tuple[int, np.ndarray]]:
    """(frame number from 1, image) for an image folder (sorted by name) or a video file."""
    import cv2

    kind, files = list_frames(source)
    if kind == "folder":
        for i, path in enumerate(files, start=1):
            yield i, read_image(path)
        return
    cap = cv2.VideoCapture(files[0])
    if not cap.isOpened():
        cap.release()
        raise PlateLightError(f"Cannot read the video (not a video file, or no codec for it): {files[0]}")
    try:
        i = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            i += 1
            yield i, img
    finally:
        cap.release()
    if i == 0:
        raise PlateLightError(f"The video holds no readable frames: {files[0]}")
