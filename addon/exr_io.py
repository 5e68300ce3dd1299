"""OpenEXR reading and writing (float32), with clear errors and atomic replacement.

Reads RGB, RGBA, Y (grey), half, float or uint, scanline or tiled, single- or multi-part, plain
or layered channel names (``diffuse.R``, ``ViewLayer.Combined.R``: the picture's layer is
chosen), returning float32 arrays of shape (H, W, C) whose first row is the top of the image. Writes float32 RGB(A) with ZIP compression
(float, not half: half overflows at 65504 and a visible sun is brighter).
"""
from __future__ import annotations

import os

import numpy as np

from .errors import PlateLightError
from .fileio import atomic_path, read_magic

EXR_MAGIC = b"\x76\x2f\x31\x01"


def read_exr(path: str | os.PathLike, channels: str = "RGB", layer: str | None = None) -> np.ndarray:
    """Read an EXR as float32 (H, W, len(channels)). ``channels`` is "RGB" or "RGBA"; ``layer``:
    the layer whose last name is this (a multilayer render's pass, "Shadow Catcher"), else the
    picture's.

    A grey (Y-only) image and a one-value pass (X only: Object Index) are broadcast to RGB, a
    vector pass's X, Y, Z read as R, G, B; a missing alpha reads as 1."""
    import OpenEXR

    path = os.fspath(path)
    if read_magic(path, "an EXR file") != EXR_MAGIC:
        raise PlateLightError(f"Not an OpenEXR file (wrong magic number): {path}")
    try:
        exr = OpenEXR.File(path, separate_channels=True)
        parts = [{name: ch.pixels for name, ch in part.channels.items()} for part in exr.parts]
    except Exception as exc:  # the library raises RuntimeError / ValueError for truncated data
        raise PlateLightError(f"Cannot read EXR (truncated or corrupt): {path} ({exc})") from None
    planes = _choose_layer(parts, layer)
    if planes is None:
        found = sorted({n for part in parts for n in part})
        wanted = f"a {layer} layer" if layer else "R, G, B or Y channels"
        raise PlateLightError(f"EXR has no {wanted} (found {', '.join(found[:12])}): {path}")
    if all(k in planes for k in "RGB"):
        rgb = [planes["R"], planes["G"], planes["B"]]
    elif all(k in planes for k in "XYZ"):          # a vector pass (Denoising Normal)
        rgb = [planes["X"], planes["Y"], planes["Z"]]
    else:
        rgb = [planes["Y"] if "Y" in planes else planes["X"]] * 3
    if channels == "RGBA":
        alpha = planes.get("A")
        rgb.append(alpha if alpha is not None else np.ones_like(rgb[0]))
    elif channels != "RGB":
        raise ValueError(f"channels must be 'RGB' or 'RGBA', not {channels!r}")
    shapes = {p.shape for p in rgb}
    if len(shapes) != 1:
        raise PlateLightError(f"EXR channels have different sizes (subsampled channels): {path}")
    return np.stack([np.asarray(p, dtype=np.float32) for p in rgb], axis=-1)


# Layer names that hold the picture in renderers' multi-layer files, most likely first.
PICTURE_LAYERS = ("", "rgba", "rgb", "combined", "beauty", "image", "color", "colour")


def _choose_layer(parts: list[dict], wanted: str | None = None) -> dict | None:
    """The channels {"R": plane, ...} of the layer that holds the picture: the unnamed layer,
    else a Combined/beauty/RGBA-like one (Blender's "ViewLayer.Combined.R"), else the first
    layer with R, G, B or Y, over all parts of a multi-part file. ``wanted``: only a layer whose
    last name is that (case-insensitive)."""
    layers: dict[str, dict] = {}
    for part in parts:
        for name, pixels in part.items():
            layer, _, channel = name.rpartition(".")
            channel = channel.upper()
            if channel in ("R", "G", "B", "A", "X", "Y", "Z"):
                layers.setdefault(layer, {}).setdefault(channel, pixels)
    usable = {k: v for k, v in layers.items()
              if all(c in v for c in "RGB") or "Y" in v or set(v) == {"X"}}
    if wanted is not None:
        usable = {k: v for k, v in usable.items() if k.rpartition(".")[2].lower() == wanted.lower()}
    if not usable:
        return None

    def rank(layer: str):
        last = layer.rpartition(".")[2].lower()
        return (PICTURE_LAYERS.index(last) if last in PICTURE_LAYERS else len(PICTURE_LAYERS),
                not all(c in usable[layer] for c in "RGB"), list(layers).index(layer))
    return usable[min(usable, key=rank)]


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
