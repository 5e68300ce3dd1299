"""Baked shadows: the CG's shadow on the phantoms, computed once per shot instead of every frame.

On a matte (Lambertian) phantom the shadow catcher's ratio — the light a point receives with the
CG there over the light without it — depends on the point only, not on the camera: the albedo
cancels and a diffuse surface sends the same radiance to every viewer. So for a shot whose CG and
phantoms stand still while the camera moves (the paper's AR case, the benchmark's orbit), the
ratio is rendered once, as an equirectangular panorama seen from a point above the CG (dense
where the shadow is sharp, right under the CG; coarser far off, where it is soft), and every
frame only looks it up along the direction to each phantom point: a nearly free emission render
instead of a path-traced catcher pass.

A CG that moves or deforms is left out of that panorama; its shadows are baked at every frame
(a panorama from above it, the still CG left out) or left to a catcher layer, and the two ratios
multiply. What it cannot do, and the operators say so: points the panorama does not see (they
get no change), glossy phantoms (their ratio depends on the view), phantoms that move.

This module is the bpy-free part: the ratio and the files."""
from __future__ import annotations

import json
import math
import os
import re

import numpy as np

from ..exr_io import write_exr
from ..ibl.distance import distance_filename
from ..fileio import write_json_atomic

RATIO_FILE = "shadow_ratio.exr"
# Cycles denoises a Shadow Catcher pass with this constant albedo and the normal (its
# denoiser_oidn: OIDN takes a normal only with an albedo); PlateLight's denoising of catcher
# passes does the same
CATCHER_ALBEDO = 0.5
RECORD_FILE = "shadow_ratio.json"
# Inside the shadows folder: a moving CG's per-frame ratio and distance panoramas
MOVING_FOLDER = "moving"
# Without the CG a texel this dark received no light worth a ratio (sky, a black phantom).
DARK = 1e-6
# The largest brightening a ratio may apply (as the compositor's Shadow Clamp).
RATIO_CLAMP = 4.0
# Rows rendered beyond the phantoms' elevations: the denoiser's context and the look-up's
# bilinear neighbours at the band's edges.
ROW_MARGIN = 24
# A band this close to the whole panorama is rendered whole (the border would save nothing).
WHOLE_BAND = 0.9


def elevation_range(centre, low, high) -> tuple[float, float]:
    """The lowest and highest elevation (radians) from ``centre`` of any point of the world box
    [low, high]: elevation rises with height and, above the centre, falls with horizontal
    distance (below it, rises), so the extremes lie at the box's top or bottom at its nearest or
    farthest horizontal distance."""
    centre, low, high = (np.asarray(v, dtype=np.float64) for v in (centre, low, high))
    nearest = np.linalg.norm(np.clip(centre[:2], low[:2], high[:2]) - centre[:2])
    farthest = np.linalg.norm(np.maximum(np.abs(low[:2] - centre[:2]), np.abs(high[:2] - centre[:2])))
    top, bottom = high[2] - centre[2], low[2] - centre[2]
    highest = math.atan2(top, nearest if top >= 0 else farthest)
    lowest = math.atan2(bottom, farthest if bottom >= 0 else nearest)
    return lowest, highest


def panorama_rows(centre, boxes, height: int) -> tuple[int, int] | None:
    """The band of rows (first, last + 1; the first row is the top) of a ``height``-row panorama
    from ``centre`` that sees every point of ``boxes`` ((low, high) world boxes: the phantoms),
    with ROW_MARGIN rows either side; None when that is (nearly) the whole panorama. The shadow
    ratio is wanted on phantom points only, and a floor's lie below the centre: half the rows."""
    if not boxes:
        return None
    ranges = [elevation_range(centre, low, high) for low, high in boxes]
    lowest, highest = min(r[0] for r in ranges), max(r[1] for r in ranges)
    first = max(0, math.floor((0.5 - highest / math.pi) * height) - ROW_MARGIN)
    last = min(height, math.ceil((0.5 - lowest / math.pi) * height) + ROW_MARGIN)
    if last - first >= WHOLE_BAND * height:
        return None
    return first, last


def shadow_ratio(lit_with: np.ndarray, lit_without: np.ndarray) -> np.ndarray:
    """Per texel and channel, with / without, 1 where nothing was lit, clamped to [0, RATIO_CLAMP]."""
    lit_with = np.asarray(lit_with, dtype=np.float64)
    lit_without = np.asarray(lit_without, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lit_without > DARK, lit_with / np.maximum(lit_without, DARK), 1.0)
    ratio[~np.isfinite(ratio)] = 1.0
    return np.clip(ratio, 0.0, RATIO_CLAMP)


def catcher_ratio(caught: np.ndarray, rows: tuple[int, int] | None = None) -> np.ndarray:
    """The ratio from Cycles' Shadow Catcher pass ``caught`` (H, W, 4; alpha the Combined pass's:
    0 where a catcher is seen, 1 where the sky is): blended to 1 over the sky (the denoised pass
    there is 1 smoothed, not 1), 1 outside the rendered ``rows`` (black there), clamped as
    shadow_ratio."""
    caught = np.asarray(caught, dtype=np.float64)
    sky = np.clip(caught[..., 3:], 0.0, 1.0)
    ratio = sky + (1.0 - sky) * caught[..., :3]
    ratio[~np.isfinite(ratio)] = 1.0
    if rows is not None:
        ratio[:rows[0]] = 1.0
        ratio[rows[1]:] = 1.0
    return np.clip(ratio, 0.0, RATIO_CLAMP)


def ratio_to_texture(ratio: np.ndarray) -> np.ndarray:
    """What the override material reads: ratio − 1, so a texel that reads 0 means "no change"."""
    return np.ascontiguousarray(np.asarray(ratio, dtype=np.float32)[..., :3] - 1.0)


def ratio_filename(frame: int | None = None) -> str:
    """The ratio texture's file: RATIO_FILE, or for a moving CG's frame ``shadow_ratio_0010.exr``."""
    if frame is None:
        return RATIO_FILE
    stem, ext = os.path.splitext(RATIO_FILE)
    return f"{stem}_{int(frame):04d}{ext}"


def write_ratio(folder: str, texture: np.ndarray, frame: int | None = None) -> str:
    """Write the ratio texture (of one frame of a moving CG's, with ``frame``) into ``folder``."""
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, ratio_filename(frame))
    write_exr(path, texture)
    return path


def moving_filenames(frame: int) -> list[str]:
    """The files of one frame of a moving CG's per-frame bake, in MOVING_FOLDER."""
    return [ratio_filename(frame), distance_filename(frame)]


def has_moving_frames(folder: str, frames) -> bool:
    """Does ``folder`` hold every file of these frames of a per-frame bake?"""
    moving = os.path.join(folder, MOVING_FOLDER)
    return all(os.path.isfile(os.path.join(moving, name)) for f in frames for name in moving_filenames(f))


def _is_frame_file(name: str) -> bool:
    """Is ``name`` one of a per-frame bake's files (moving_filenames of the frame it is numbered)?"""
    number = re.search(r"_(\d+)\.exr$", name)
    return number is not None and name in moving_filenames(int(number.group(1)))


def remove_moving_frames(folder: str, keep=()) -> list[str]:
    """Delete the per-frame bake's files of frames not in ``keep`` (a shorter shot, or the moving
    CG's shadows now left to the catcher), so no old frame is ever read. Returns the files removed."""
    moving = os.path.join(folder, MOVING_FOLDER)
    if not os.path.isdir(moving):
        return []
    wanted = {name for f in keep for name in moving_filenames(f)}
    removed = sorted(n for n in os.listdir(moving) if _is_frame_file(n) and n not in wanted)
    for name in removed:
        os.unlink(os.path.join(moving, name))
    return removed


def write_record(folder: str, centre, height: int, samples: int, digest: str = "", method: str = "",
                 denoiser: str = "", moving: dict | None = None) -> None:
    """Write the bake's record (the panorama's centre, the bake's settings, the inputs' hash, and
    for a shot with moving CG which, how their shadows are made and each frame's centre) into
    ``folder``; written last, so a bake stopped halfway is never taken as current."""
    record = {"centre": [float(v) for v in centre], "height": int(height), "samples": int(samples),
              "method": method, "denoiser": denoiser, "hash": digest}
    if moving:
        record["moving"] = moving
    write_json_atomic(os.path.join(folder, RECORD_FILE), record)


def read_record(folder: str) -> dict | None:
    """The record of a bake in ``folder``, or None when there is none or it is unreadable."""
    try:
        with open(os.path.join(folder, RECORD_FILE), encoding="utf-8") as f:
            record = json.load(f)
        centre = [float(v) for v in record["centre"]]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if len(centre) != 3 or not all(math.isfinite(v) for v in centre):
        return None
    return record
