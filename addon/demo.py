"""`python -m platelight demo --out DIR`: the embedded end-to-end example, no arguments needed.

Stage 1 (engine): the four maps of a CC0 HDRI that ships inside the bpy wheel, with a contact
sheet PNG (probe | diffuse | glossy1 | glossy2 | specular). Stage 2 (headless Blender): the AR
composite of addon/demo_ar.py (plate, per-object probes, SBRDF materials, shadows, differential
composite) and a row of spheres with the SBRDF material presets."""
from __future__ import annotations

import glob
import importlib.util
import os
import time

from .errors import PlateLightError
from .exr_io import read_exr
from .fileio import ensure_writable_folder, write_json_atomic
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


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="run the embedded end-to-end example",
                       description="Maps of a bundled HDRI and the AR composite demo.")
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output folder (default out/demo)")
    p.add_argument("--hdri", default=DEFAULT_HDRI, help="bundled HDRI name (default: sunset)")
    p.add_argument("--maps-only", action="store_true", help="skip the Blender AR stage")
    p.set_defaults(func=run)


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


def run(args) -> int:
    out = ensure_writable_folder(args.out)
    timings = {"maps": run_maps_stage(out, args.hdri)}
    print(f"maps of '{args.hdri}' in {timings['maps']['maps_s'] * 1e3:.1f} ms -> {out}/maps, "
          f"{out}/maps_contact_sheet.png")
    if not args.maps_only:
        from .demo_ar import EXT_MODULE, blender_with_extension, run_ar_demo

        timings["ar"] = run_ar_demo(os.path.join(out, "ar"))
        print(f"AR composite: {out}/ar/contact_sheet.png, composites in {out}/ar/composite/")
        # The material presets, one sphere each (the paper's materials, Figure 15).
        blender_with_extension()
        preview = importlib.import_module(f"{EXT_MODULE}.node_groups.sbrdf_preview")
        t0 = time.perf_counter()
        preview.render_preset_row(os.path.join(out, "sbrdf_presets.png"))
        timings["sbrdf_presets_s"] = time.perf_counter() - t0
        print(f"material presets: {out}/sbrdf_presets.png")
    write_json_atomic(os.path.join(out, "timings.json"), timings)
    print(f"timings: {out}/timings.json")
    return 0
