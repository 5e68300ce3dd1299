"""`python -m platelight demo --out DIR`: the embedded end-to-end example, no arguments needed.

Stage 1 (engine, addon/demo.py): the four maps of a bundled HDRI and their contact sheet.
Stage 2 (headless Blender): the AR composite of drivers/demo_ar.py (plate, per-object probes,
SBRDF materials, baked shadows, the composite beside the path-traced truth) and a row of spheres
with the SBRDF material presets. Blender's own output goes to blender.log; the terminal gets the
stages and their seconds."""
from __future__ import annotations

import importlib
import os
import time

from ..addon.demo import DEFAULT_HDRI, run_maps_stage
from ..addon.farm.progress import blender_output
from ..addon.errors import PlateLightError
from ..addon.fileio import ensure_writable_folder, write_json_atomic


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="run the embedded end-to-end example",
                       description="Maps of a bundled HDRI and the AR composite demo.")
    p.add_argument("--out", default="out/demo", metavar="DIR", help="output folder (default out/demo)")
    p.add_argument("--hdri", default=DEFAULT_HDRI, help="bundled HDRI name (default: sunset)")
    p.add_argument("--maps-only", action="store_true", help="skip the Blender AR stage")
    p.add_argument("--frames", type=int, default=None, metavar="N",
                   help="frames of the AR shot (default 3)")
    p.add_argument("--size", default=None, metavar="WxH", help="the AR shot's size (default 640x360)")
    p.set_defaults(func=run)


def _size(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise PlateLightError(f"Cannot read the size {text!r}; write it like 640x360.") from None
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise PlateLightError(f"The size {text} is outside 16x16 to 8192x8192.")
    return width, height


def run(args) -> int:
    out = ensure_writable_folder(args.out)
    timings = {"maps": run_maps_stage(out, args.hdri)}
    print(f"maps of '{args.hdri}' in {timings['maps']['maps_s'] * 1e3:.1f} ms -> {out}/maps, "
          f"{out}/maps_contact_sheet.png", flush=True)
    if not args.maps_only:
        from .demo_ar import FRAMES, SIZE, run_ar_demo
        from .headless import EXT_MODULE, blender_with_extension

        log_path = os.path.join(out, "blender.log")
        with open(log_path, "w"):
            pass                        # each run's log starts empty
        print(f"AR composite (Blender's own log: {log_path}):", flush=True)
        with blender_output(False, log_path) as progress:
            def say(line):
                print(line, file=progress, flush=True)

            timings["ar"] = run_ar_demo(os.path.join(out, "ar"), frames=args.frames or FRAMES,
                                        size=_size(args.size) if args.size else SIZE, say=say)
            # The material presets, one sphere each (the paper's materials, Figure 15).
            blender_with_extension()
            preview = importlib.import_module(f"{EXT_MODULE}.node_groups.sbrdf_preview")
            t0 = time.perf_counter()
            preview.render_preset_row(os.path.join(out, "sbrdf_presets.png"))
            timings["sbrdf_presets_s"] = time.perf_counter() - t0
        print(f"AR composite: {out}/ar/truth_comparison.png (beside the path-traced truth), "
              f"{out}/ar/contact_sheet.png, composites in {out}/ar/composite/; material presets: "
              f"{out}/sbrdf_presets.png")
    write_json_atomic(os.path.join(out, "timings.json"), timings)
    print(f"timings: {out}/timings.json")
    return 0
