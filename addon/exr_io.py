"""OpenEXR reading and writing (float32), with clear errors and atomic replacement.

Reads RGB, RGBA, Y (grey), half or float, scanline or tiled, returning float32 arrays of shape
(H, W, C) whose first row is the top of the image. Writes float32 RGB(A) with ZIP compression
(float, not half: half overflows at 65504 and a visible sun is brighter).
"""
from __future__ import annotations

import os

import numpy as np

from .errors import PlateLightError
from .fileio import atomic_path

EXR_MAGIC = b"\x76\x2f\x31\x01"


def read_exr(path: str | os.PathLike, channels: str = "RGB") -> np.ndarray:
    """Read an EXR as float32 (H, W, len(channels)). ``channels`` is "RGB" or "RGBA".

    A grey (Y-only) image is broadcast to RGB; a missing alpha reads as 1."""
    import OpenEXR

    path = os.fspath(path)
    if not os.path.exists(path):
        raise PlateLightError(f"File not found: {path}")
    if os.path.isdir(path):
        raise PlateLightError(f"Expected an EXR file but got a folder: {path}")
    with open(path, "rb") as fh:
        magic = fh.read(4)
    if magic != EXR_MAGIC:
        raise PlateLightError(f"Not an OpenEXR file (wrong magic number): {path}")
    try:
        exr = OpenEXR.File(path, separate_channels=True)
        part_channels = exr.channels()
    except Exception as exc:  # the library raises RuntimeError / ValueError for truncated data
        raise PlateLightError(f"Cannot read EXR (truncated or corrupt): {path} ({exc})") from None

    planes = {name.split(".")[-1].upper(): ch.pixels for name, ch in part_channels.items()}
    if all(k in planes for k in "RGB"):
        rgb = [planes["R"], planes["G"], planes["B"]]
    elif "Y" in planes:
        rgb = [planes["Y"]] * 3
    else:
        raise PlateLightError(f"EXR has no R, G, B or Y channels (found {sorted(planes)}): {path}")
    if channels == "RGBA":
        alpha = planes.get("A")
        rgb.append(alpha if alpha is not None else np.ones_like(rgb[0]))
    elif channels != "RGB":
        raise ValueError(f"channels must be 'RGB' or 'RGBA', not {channels!r}")
    shapes = {p.shape for p in rgb}
    if len(shapes) != 1:
        raise PlateLightError(f"EXR channels have different sizes (subsampled channels): {path}")
    return np.stack([np.asarray(p, dtype=np.float32) for p in rgb], axis=-1)


def write_exr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write float32 RGB or RGBA (H, W, 3|4) atomically: a temporary file in the same folder is
    renamed over ``path``, so a reader never sees a half-written map."""
    import OpenEXR

    path = os.fspath(path)
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"write_exr needs an (H, W, 3|4) array, got shape {image.shape}")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise PlateLightError(f"Cannot create output folder {folder}: {exc.strerror}") from None
    if not os.access(folder, os.W_OK):
        raise PlateLightError(f"Output folder is not writable: {folder}")
    data = np.ascontiguousarray(image, dtype=np.float32)
    names = "RGBA"[: data.shape[2]]
    channels = {n: np.ascontiguousarray(data[..., i]) for i, n in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        OpenEXR.File(header, channels).write(tmp)
