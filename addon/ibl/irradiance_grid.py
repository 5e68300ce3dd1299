"""Irradiance grids: the diffuse map as seen from points around the object, not only from its
centre (bpy-free).

A probe's diffuse map is the irradiance at the probe's centre. A point low on a ball resting on
a floor faces the same floor from much closer: from the centre, the shadowed floor under the ball
fills the directions straight down; from the surface point it covers a small solid angle and the
lit floor further out fills the rest. One irradiance map has no parallax, so the ball's lower
half came out 2-5 % dark (docs/decisions.md).

The probe's radiance and distance panoramas hold enough to see from elsewhere: for every
direction of a panorama around a point p the distance-impostor search (distance.py, the same the
specular look-ups use) finds the surface that direction meets, and the probe's radiance of that
surface is what p sees there. The sky (FAR) keeps its direction. Each grid point's panorama then
becomes a diffuse map exactly as the centre's does (maps.py: exact SH, clamped-cosine lobe), and
the shader blends the eight maps around the shading point trilinearly
(node_groups/probe_maps.py). Surfaces hidden from the centre but visible from p are not in the
probe; the search returns what lies in front of or behind them (as for the specular look-ups).

The grid spans the object's bounding box inset by INSET of its size (a resting object's box
touches the floor, and a point on the floor sees it at zero distance). A grid point that lies
beyond a surface the centre sees (inside a phantom the object reaches into) is pulled back along
its direction to just in front of that surface.

The maps are stored side by side in one atlas image, each padded by one texel (wrapped across
the seam, repeated at the poles) so the image's bilinear filter never mixes neighbours.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..exr_io import write_exr
from ..fileio import remove_if_present
from . import sh
from .distance import FAR, _equirect_lookup, parallax_directions
from .equirect import dir_to_uv, downsample_area, sample_bilinear, texel_directions

GRID_NAME = "diffuse_grid"
RECORD_KEY = "irradiance_grid"   # the bake record's entry: box corners, points per axis, map height
VERSION = 1                      # part of the probe hash: bakes without a grid are redone
DEFAULT_POINTS = 4               # per axis: 64 maps; 3 measured worse on the resting ball
INSET = 0.02                     # of the box's size per side
IN_FRONT = 0.98                  # a buried grid point moves to this fraction of the surface's distance
PAD = 1                          # texels around each map in the atlas
# Each grid point's panorama is built (one distance search per texel) at most this high: the cost
# is per texel and per point, and a probe sized to a mirror on screen can be 1024 px high
# (64 points x 2M texels). Irradiance is smooth; the area-downsampled probe keeps every light's
# energy.
ANALYSIS_HEIGHT = 64
# Points per thread's task: the bake's costliest numpy step, 2.2x faster on two cores than one
# search over all 64 points (smaller arrays stay in cache).
CHUNK_POINTS = 8


def grid_filename(frame: int | None = None) -> str:
    return f"{GRID_NAME}.exr" if frame is None else f"{GRID_NAME}_{int(frame):04d}.exr"


def grid_box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """The grid's corners for an object's bounding box (world space), inset by INSET per side;
    a flat axis (a plane) keeps its one value."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    margin = INSET * (hi - lo)
    return lo + margin, hi - margin


def grid_points(lo, hi, n: int) -> np.ndarray:
    """The grid's points, (n³, 3), in tile order: index = i + n j + n² k for x, y, z steps
    i, j, k (the shader computes the same index)."""
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([x, y, z], axis=-1).reshape(-1, 3)


def unburied(offsets: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Offsets from the centre moved in front of the surface the centre sees in their direction
    when they lie beyond it (a grid point inside a phantom)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    reach = np.linalg.norm(offsets, axis=-1)
    surface = _equirect_lookup(distance, offsets).astype(np.float64)
    beyond = (reach > IN_FRONT * surface) & (surface < FAR)
    scale = np.where(beyond, IN_FRONT * surface / np.maximum(reach, 1e-12), 1.0)
    return offsets * scale[:, None]


def panoramas_from(radiance: np.ndarray, distance: np.ndarray, offsets) -> np.ndarray:
    """The probe's radiance as seen from each of ``offsets`` (points relative to the probe
    centre), (N, h, w, 3): each texel direction followed to the surface it meets (one
    distance-impostor search for all points, in float32: the bake's costliest numpy step), the
    radiance read along the corrected direction (bilinear, as an Environment Texture does)."""
    h, w = radiance.shape[:2]
    offsets = np.asarray(offsets, dtype=np.float32).reshape(-1, 1, 1, 3)
    dirs = texel_directions(h, w).astype(np.float32)
    look = parallax_directions(distance, offsets, dirs)
    u, v = dir_to_uv(look, np.float32)
    panoramas = sample_bilinear(radiance, u, v, np.float32)
    panoramas[~np.any(offsets, axis=-1).reshape(-1)] = radiance      # the centre sees the probe itself
    return panoramas


def irradiance_maps(radiance: np.ndarray, distance: np.ndarray, offsets, height: int,
                    lmax: int, workers: int | None = None) -> np.ndarray:
    """Diffuse maps (E/π, as maps.py's diffuse map) at each offset, (N, height, 2 height, 3).

    The panorama is analysed at the probe's resolution (area-downsampled to ANALYSIS_HEIGHT at
    most) and synthesised at ``height``; the clamped cosine's SH factors up to ``lmax``
    (maps.DIFFUSE_LMAX_EXACT at most). ``workers``: threads (None: one per core)."""
    radiance = np.asarray(radiance, dtype=np.float32)[..., :3]
    if radiance.shape[0] > ANALYSIS_HEIGHT:
        radiance = downsample_area(radiance, ANALYSIS_HEIGHT)
    lmax = min(lmax, max(2, radiance.shape[0] - 1))
    factors = sh.lobe_factors(1.0, lmax)
    points = unburied(np.asarray(offsets, dtype=np.float64).reshape(-1, 3), distance)

    def maps_of(chunk):
        return [np.maximum(sh.synthesize(sh.project_exact(panorama, lmax), height, factors), 0.0)
                for panorama in panoramas_from(radiance, distance, chunk)]

    # numpy releases the GIL in its loops: a few points per thread, on every core
    chunks = [points[i:i + CHUNK_POINTS] for i in range(0, len(points), CHUNK_POINTS)]
    with ThreadPoolExecutor(max_workers=max(1, min(len(chunks), workers or os.cpu_count() or 1))) as pool:
        return np.asarray([m for maps in pool.map(maps_of, chunks) for m in maps], dtype=np.float32)


def atlas(maps: np.ndarray) -> np.ndarray:
    """The maps (N, h, w, 3) side by side, each padded by PAD texels: columns wrap around the
    seam, rows repeat at the poles. Shape (h + 2 PAD, N (w + 2 PAD), 3)."""
    maps = np.asarray(maps, dtype=np.float32)
    padded = np.concatenate([maps[:, :, -PAD:], maps, maps[:, :, :PAD]], axis=2)
    padded = np.concatenate([padded[:, :1].repeat(PAD, axis=1), padded,
                             padded[:, -1:].repeat(PAD, axis=1)], axis=1)
    return np.concatenate(list(padded), axis=1)


def atlas_uv(tile, u, v, n_tiles: int, height: int) -> tuple:
    """Image coordinates in the atlas of map ``tile`` at its own equirect (u, v): the formula
    the shader builds from nodes (image v = 0 at the bottom row, as Blender's Image Texture)."""
    width = 2 * height
    tile_w, tile_h = width + 2 * PAD, height + 2 * PAD
    x = (np.asarray(tile, dtype=np.float64) * tile_w + PAD + np.asarray(u) * width) / (n_tiles * tile_w)
    y = (PAD + np.asarray(v) * height) / tile_h
    return x, y


def trilinear(box_lo, box_hi, n: int, points) -> tuple[np.ndarray, np.ndarray]:
    """(tiles (..., 8) int, weights (..., 8)) of the grid maps around ``points`` (world space,
    clamped into the box): the shader's blend."""
    size = np.where(np.asarray(box_hi) > np.asarray(box_lo), np.asarray(box_hi) - np.asarray(box_lo), 1.0)
    g = np.clip((np.asarray(points, dtype=np.float64) - box_lo) / size, 0.0, 1.0) * (n - 1)
    i0 = np.minimum(np.floor(g), n - 2)
    f = g - i0
    tiles, weights = [], []
    for corner in range(8):
        step = np.array([(corner >> a) & 1 for a in range(3)])
        index = i0 + step
        tiles.append(index[..., 0] + n * index[..., 1] + n * n * index[..., 2])
        weights.append(np.prod(np.where(step == 1, f, 1.0 - f), axis=-1))
    return np.stack(tiles, axis=-1).astype(int), np.stack(weights, axis=-1)


def write_grid(folder, image: np.ndarray, frame: int | None = None) -> str:
    path = os.path.join(os.fspath(folder), grid_filename(frame))
    write_exr(path, image)
    return path


def remove_grid(folder, frame: int | None = None) -> None:
    """Remove a grid no longer wanted (the object turned metallic, or Diffuse Parallax off)."""
    remove_if_present(os.path.join(os.fspath(folder), grid_filename(frame)))
