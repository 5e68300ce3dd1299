"""Equirectangular (lat-long) geometry in the convention of Blender's Environment Texture node.

``u = atan2(-d.y, d.x) / 2π + 0.5`` (+X at the image centre, +Y at u = 0.25),
``v = atan2(d.z, hypot(d.x, d.y)) / π + 0.5``; width = 2 × height; row 0 of an array is the top
(v = 1). Texel (i, j) has its centre at u = (j + 0.5)/W, v = 1 − (i + 0.5)/H.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import PlateLightError


def uv_to_dir(u, v):
    """Unit directions (..., 3) for texture coordinates u, v in [0, 1]."""
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    azimuth = 2.0 * np.pi * (u - 0.5)          # = atan2(-y, x)
    elevation = np.pi * (v - 0.5)
    c = np.cos(elevation)
    return np.stack([c * np.cos(azimuth), -c * np.sin(azimuth), np.sin(elevation)], axis=-1)


def dir_to_uv(d, dtype=np.float64):
    """Texture coordinates (u, v) of directions (..., 3); they need not be normalised.
    ``dtype`` float32 halves the time where that is precise enough (the bake's searches)."""
    d = np.asarray(d, dtype=dtype)
    return xyz_to_uv(d[..., 0], d[..., 1], d[..., 2])


def xyz_to_uv(x, y, z):
    """dir_to_uv of directions given as component arrays, in their precision. (sqrt(x² + y²),
    not hypot: numpy's hypot is 5-15x slower, and the bake's distance searches call this
    millions of times.)"""
    u = np.arctan2(-y, x) * (0.5 / np.pi) + 0.5
    v = np.arctan2(z, np.sqrt(x * x + y * y)) * (1.0 / np.pi) + 0.5
    return u, v


def row_elevations(height: int) -> np.ndarray:
    """Elevation (radians, +π/2 at the top) of each row's centre, top row first."""
    return np.pi * (0.5 - (np.arange(height) + 0.5) / height)


@lru_cache(maxsize=32)
def texel_directions(height: int, width: int) -> np.ndarray:
    """Unit direction of every texel centre, shape (H, W, 3), read-only (cached)."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    dirs = uv_to_dir(u[None, :], v[:, None])
    dirs.setflags(write=False)
    return dirs


@lru_cache(maxsize=32)
def row_solid_angles(height: int, width: int) -> np.ndarray:
    """Exact solid angle of one texel in each row, shape (H,): (2π/W)·(sin top − sin bottom)."""
    edges = np.pi * (0.5 - np.arange(height + 1) / height)
    sa = (2.0 * np.pi / width) * (np.sin(edges[:-1]) - np.sin(edges[1:]))
    sa.setflags(write=False)
    return sa


def texel_solid_angles(height: int, width: int) -> np.ndarray:
    """Exact solid angle of every texel, shape (H, W); they add up to 4π."""
    return np.broadcast_to(row_solid_angles(height, width)[:, None], (height, width))


def check_shape(image: np.ndarray, name: str = "environment map") -> None:
    """Reject images that are not usable lat-long maps, with one clear sentence."""
    if image.ndim != 3 or image.shape[2] < 3:
        raise PlateLightError(f"The {name} must be an RGB image, got an array of shape {image.shape}.")
    h, w = image.shape[:2]
    if w != 2 * h:
        raise PlateLightError(
            f"The {name} is {w}×{h}; an equirectangular (lat-long) map must be twice as wide as high.")
    if h < 4:
        raise PlateLightError(f"The {name} is only {w}×{h} pixels; it needs at least 8×4.")


def downsample_area(image: np.ndarray, height: int) -> np.ndarray:
    """Area-correct (solid-angle weighted box) downsampling of a lat-long map to ``height`` rows.

    Exact when the source height is a multiple of ``height``; otherwise the map is first
    resampled bilinearly to the nearest multiple above. Upsampling is bilinear."""
    h, w = image.shape[:2]
    width = 2 * height
    if height == h:
        return np.asarray(image, dtype=np.float32).copy()
    if height > h:
        return resample_bilinear(image, height, width)
    factor = -(-h // height)
    if h != factor * height:
        image = resample_bilinear(image, factor * height, factor * width)
        h, w = image.shape[:2]
    # Texel weights are per row: sum each block's columns first (strided adds are much faster
    # than a reduction over a short axis), then weight and add the rows.
    weights = row_solid_angles(h, w)                                   # (h,)
    col_sums = np.zeros((h, width, image.shape[2]))
    for k in range(factor):
        col_sums += image[:, k::factor]
    col_sums *= weights[:, None, None]
    block = np.zeros((height, width, image.shape[2]))
    for k in range(factor):
        block += col_sums[k::factor]
    block_weight = weights.reshape(height, factor).sum(axis=1) * factor
    return (block / block_weight[:, None, None]).astype(np.float32)


def sample_bilinear(image: np.ndarray, u, v, dtype=np.float64) -> np.ndarray:
    """Bilinear lookup of a lat-long map at (u, v), wrapping in u and clamping in v
    (what a GPU does with a repeat/extend sampler). Returns (..., C) in ``dtype``."""
    h, w = image.shape[:2]
    x = np.asarray(u, dtype=dtype) * w - 0.5
    y = (1.0 - np.asarray(v, dtype=dtype)) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y0i = np.clip(y0.astype(np.int64), 0, h - 1)
    y1i = np.clip(y0.astype(np.int64) + 1, 0, h - 1)
    img = np.asarray(image, dtype=dtype)
    top = img[y0i, x0] * (1 - fx) + img[y0i, x1] * fx
    bottom = img[y1i, x0] * (1 - fx) + img[y1i, x1] * fx
    return top * (1 - fy) + bottom * fy


def resample_bilinear(image: np.ndarray, height: int, width: int) -> np.ndarray:
    """Bilinear resampling of a lat-long map onto another texel grid."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    return sample_bilinear(image, u[None, :], v[:, None]).astype(np.float32)


def from_pbrt_latlong(image: np.ndarray) -> np.ndarray:
    """Convert a pbrt-layout lat-long map (top row +z, u = φ/2π, φ = atan2(y, x)) to this
    module's layout. Ours has u = 0.5 − φ/2π, so column j takes pbrt column (W/2 − 1 − j) mod W:
    an exact permutation of columns, no resampling."""
    w = image.shape[1]
    cols = (w // 2 - 1 - np.arange(w)) % w
    return np.ascontiguousarray(image[:, cols])


def rotate_equirect(image: np.ndarray, rotation) -> np.ndarray:
    """The lat-long map that shows in direction d what ``image`` shows in direction
    ``rotation @ d`` (bilinear). A turn about Z keeps every texel in its row, so only the row is
    interpolated; a turn by a multiple of one texel is an exact shift."""
    check_shape(image)
    h, w = image.shape[:2]
    source = texel_directions(h, w) @ np.asarray(rotation, dtype=np.float64).T
    u, v = dir_to_uv(source)
    return sample_bilinear(image, u, v).astype(np.float32)
