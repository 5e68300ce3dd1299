"""Shadow bake settings (issue 11): what the baked route's shadow costs and how close it gets to the
path-traced truth, per method, panorama height, samples, denoiser setting and diffuse bounces
(docs/decisions.md, "The shadow bake renders only the rows that see a phantom" and "The shadow
bake's diffuse bounces").

The composite benchmark's diffuse scene (bench_composite.py: its shot, its cached 512-spp truth;
`make bench` runs that benchmark first), the baked route with 1 CG sample, the shadows baked with
`bake_shadows(height, samples, method)` and the scene's Cycles denoiser settings, which the bake's
renders keep. Methods: *two renders* (the panorama with the CG, the distance map, the panorama
without it; the ratio divided in numpy) and *catcher* (one render of the Shadow Catcher pass with
the phantoms as catchers, then the distance map), its pass denoised by the compositor's Denoise node
alone (*catcher, compositor*, the default) or by Cycles with Combined and the matte (*catcher,
Cycles*); the compositor never prefilters the pass's guides. *Diffuse
bounces*: the bake's (its cap, SHADOW_BAKE_DIFFUSE_BOUNCES, or the scene's 4 below it; rows without
the column rendered with the scene's 4). Bake seconds include the sphere's probe bake; *renders*
are the shadow bake's renders in that order (the compositor's denoise among them), timed by
render_pre and render_post handlers. PSNR as in bench_composite (frame 24, peak the truth's 99.5th
percentile); *shadow bias*: the mean of (composite − truth) / plate over the shadow (luminance; >
0: too light). Timings on this 2-core machine vary by about 15 % between identical runs.

Run: `PLATELIGHT_BENCH_SIZE=960x540 .venv/bin/python tests/bench/run_all.py --only shadow_bake`
(about 10 minutes once the composite benchmark's truths are cached; longer without)."""
from __future__ import annotations

import importlib
import os
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_composite as bc  # noqa: E402

SCENE = "diffuse"
# (method[/catcher denoiser], rows, samples, denoiser prefilter, input passes, quality, diffuse
# bounces): Cycles' defaults and the bake's bounce cap (baked_shadows.SHADOW_BAKE_DIFFUSE_BOUNCES;
# the scene's 4 above it) unless named. The compositor never prefilters the catcher's guides (pass_denoise.py).
SETTINGS = [(method, height, samples, None, None, None, None)
            for height, samples in ((512, 1), (512, 4), (512, 8), (512, 16), (512, 64), (1024, 16))
            for method in ("TWO_RENDERS", "CATCHER/CYCLES", "CATCHER/COMPOSITOR")] + \
           [("TWO_RENDERS", 512, 16, "FAST", None, None, None), ("TWO_RENDERS", 512, 16, None, "RGB", None, None),
            ("TWO_RENDERS", 512, 16, None, None, "BALANCED", None),
            ("CATCHER/CYCLES", 512, 16, None, "RGB", None, None),
            ("CATCHER/COMPOSITOR", 512, 16, None, "RGB", None, None)] + \
           [("CATCHER/COMPOSITOR", height, samples, None, None, None, bounces)
            for height, samples in ((512, 4), (512, 8), (512, 16), (768, 8), (768, 16), (1024, 8))
            for bounces in (2, 4)] + \
           [("CATCHER/COMPOSITOR", height, samples, None, None, None, None) for height, samples in ((768, 8), (768, 16), (1024, 8))]
# PLATELIGHT_BENCH_SHADOW_ROWS="CATCHER/COMPOSITOR:512:16,TWO_RENDERS:512:16:FAST,CATCHER/COMPOSITOR:512:16:B4":
# only those rows (a fourth field: the row with that denoiser setting or bounce cap)
ONLY = {tuple(v.split(":")) for v in os.environ.get("PLATELIGHT_BENCH_SHADOW_ROWS", "").split(",") if v}


def main(out_dir: pathlib.Path) -> None:
    bc.W, bc.H = (int(v) for v in bc.SIZE.split("x"))
    bpy = bc.conftest._import_bpy_with_extension()
    hdri = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{bc.HDRI}.exr")
    material_name, box = bc.SHOT_SCENES[SCENE]
    material = bc.MATERIALS[material_name]
    truths, plates, plate_path = bc.shot_truths(bpy, hdri, SCENE, material, box, bc.CACHE / bc.SIZE)
    bc.build(bpy, hdri, material, bc.shot_camera(bc.SHOT_FRAMES, box), None)
    obj, shadow = bc.masks(truths[-1], plates[-1])
    plate_luminance = plates[-1].mean(axis=-1)
    peak = float(np.percentile(truths[-1], 99.5))
    renders = []

    def started(*_):
        renders.append(-time.perf_counter())

    def finished(*_):
        renders[-1] += time.perf_counter()

    rows = []
    baked_shadows = importlib.import_module(f"{bc.support.EXT_MODULE}.operators.baked_shadows")
    default_bounces = baked_shadows.SHADOW_BAKE_DIFFUSE_BOUNCES
    for method, height, samples, prefilter, passes, quality, bounces in SETTINGS:
        extra = (prefilter, passes, quality, bounces and f"B{bounces}")
        if ONLY and (method, str(height), str(samples), *(v for v in extra if v)) not in ONLY:
            continue

        def bake(bpy_, route, method=method.split("/")[0], denoiser=(method.split("/") + ["CYCLES"])[1],
                 height=height, samples=samples, prefilter=prefilter, passes=passes, quality=quality,
                 bounces=bounces or default_bounces):
            cycles = bpy_.context.scene.cycles
            for attr, value in (("denoising_prefilter", prefilter), ("denoising_input_passes", passes),
                                ("denoising_quality", quality)):
                if value is not None:
                    setattr(cycles, attr, value)
            renders.clear()
            baked_shadows.SHADOW_BAKE_DIFFUSE_BOUNCES = bounces    # the bench's knob, put back below
            bpy_.app.handlers.render_pre.append(started)
            bpy_.app.handlers.render_post.append(finished)
            t0 = time.perf_counter()
            try:
                # force: a row's folder may hold an earlier run's bake, which would be reused
                assert bpy_.ops.platelight.bake_shadows(height=height, samples=samples, method=method,
                                                        denoiser=denoiser, force=True) == {"FINISHED"}
            finally:
                baked_shadows.SHADOW_BAKE_DIFFUSE_BOUNCES = default_bounces
                bpy_.app.handlers.render_pre.remove(started)
                bpy_.app.handlers.render_post.remove(finished)
            return time.perf_counter() - t0

        bc.bake_route_shadows = bake
        tag = (f"shadow_bake_{method.lower().replace('/', '_')}_{height}_{samples}_"
               f"{''.join(str(v) for v in extra if v)}")
        images, bake_s, _setup_s, _seconds = bc.composite_shot(bpy, hdri, material, box, "sbrdf_baked", 1,
                                                               plate_path, bc.CACHE / bc.SIZE / tag)
        image = images[-1]
        row = dict(method=method, height=height, samples=samples, denoiser=", ".join(
            v for v in (prefilter and f"prefilter {prefilter.title()}", passes and f"input {passes}",
                        quality and f"quality {quality.title()}") if v) or "Cycles' defaults",
            bounces=min(4, bounces or default_bounces), bake_s=bake_s, renders=[round(r, 1) for r in renders],
            shadow=bc.psnr(image, truths[-1], shadow, peak), object=bc.psnr(image, truths[-1], obj, peak),
            bias=float(np.mean(((image.mean(axis=-1) - truths[-1].mean(axis=-1)) / plate_luminance)[shadow])))
        rows.append(row)
        print(row, flush=True)
    write_report(out_dir, rows)


def write_report(out_dir, rows):
    stem = os.environ.get("PLATELIGHT_BENCH_SHADOW_STEM") or \
        ("shadow_bake" if bc.SIZE == "480x270" else f"shadow_bake_{bc.SIZE}")
    header = ["| method | rows | spp | denoiser | diffuse bounces | bake (s) | renders (s) | PSNR shadow | shadow bias | PSNR object |",
              "|---|---:|---:|---|---:|---:|---|---:|---:|---:|"]
    lines = []
    for r in rows:
        method = {"TWO_RENDERS": "two renders", "CATCHER/CYCLES": "catcher, Cycles",
                  "CATCHER/COMPOSITOR": "catcher, compositor"}[r["method"]]
        lines.append(f"| {method} | {r['height']} | {r['samples']} | {r['denoiser']} | {r.get('bounces', 4)} | {r['bake_s']:.1f} | "
                     f"{' / '.join(f'{v:.1f}' for v in r['renders'])} | {r['shadow']:.2f} | {r['bias']:+.4f} | {r['object']:.2f} |")
    bc.write_table(out_dir, stem, f"# Shadow bake settings at {bc.SIZE.replace('x', '×')} (issue 11)", __doc__,
                   "bench_shadow_bake.py", header, lines)


if __name__ == "__main__":
    main(bc.support.REPO / "docs" / "bench")
