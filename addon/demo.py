"""The engine's stage of `python -m platelight demo` (drivers/demo.py): the four maps of a CC0
HDRI that ships inside the bpy wheel, with a contact sheet PNG (probe | diffuse | glossy1 |
glossy2 | specular). Runs without Blender."""
from __future__ import annotations

import glob
import importlib.util
import os
import time

from .errors import PlateLightError
from .exr_io import read_exr
from .ibl.maps import MAP_NAMES, compute_maps, write_maps
from .imaging import auto_exposure, contact_sheet, preview, write_png

DEFAULT_HDRI = "sunset"


def bundled_hdris() -> dict:
    """name -> path of the Poly Haven HDRIs inside the installed bpy wheel (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise PlateLightError("The bpy module is not installed; run `make demo` to set it up.")
    root = list(spec.submodule_search_locations)[0]
    paths = glob.glob(os.path.join(root, "*", "datafiles", "studiolights", "world", "*.exr"))
    return {os.path.splitext(os.path.basename(p))[0]: p for p in sorted(paths)}


def run_maps_stage(out: str, hdri: str) -> dict:
    hdris = bundled_hdris()
    if hdri not in hdris:
        raise PlateLightError(f"No bundled HDRI named {hdri!r}; choose one of {', '.join(hdris)}.")
    timings = {}
    t0 = time.perf_counter()
    env = read_exr(hdris[hdri])
    timings["read_probe_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = compute_maps(env)
    timings["maps_s"] = time.perf_counter() - t0
    write_maps(os.path.join(out, "maps"), result.maps)
    exposure = auto_exposure(env)
    tiles = [(f"probe ({hdri})", preview(env, exposure))]
    tiles += [(name, preview(result.maps[name], exposure)) for name in MAP_NAMES]
    write_png(os.path.join(out, "maps_contact_sheet.png"), contact_sheet(tiles))
    return timings
