"""`python -m platelight demo --out DIR`: the embedded end-to-end example, no arguments needed.

Stage 1 (engine, addon/demo.py): the four maps of a bundled HDRI and their contact sheet.
Stage 2 (headless Blender): the AR composite of drivers/demo_ar.py (plate, per-object probes,
SBRDF materials, shadows, differential composite) and a row of spheres with the SBRDF material
presets."""
from __future__ import annotations

import importlib
import os
import time

from ..addon.demo import DEFAULT_HDRI, run_maps_stage
from ..addon.fileio import ensure_writable_folder, write_json_atomic


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="run the embedded end-to-end example",
                       description="Maps of a bundled HDRI and the AR composite demo.")
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output folder (default out/demo)")
    p.add_argument("--hdri", default=DEFAULT_HDRI, help="bundled HDRI name (default: sunset)")
    p.add_argument("--maps-only", action="store_true", help="skip the Blender AR stage")
    p.set_defaults(func=run)


def run(args) -> int:
    out = ensure_writable_folder(args.out)
    timings = {"maps": run_maps_stage(out, args.hdri)}
    print(f"maps of '{args.hdri}' in {timings['maps']['maps_s'] * 1e3:.1f} ms -> {out}/maps, "
          f"{out}/maps_contact_sheet.png")
    if not args.maps_only:
        from .demo_ar import run_ar_demo
        from .headless import EXT_MODULE, blender_with_extension

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
