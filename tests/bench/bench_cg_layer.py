"""The CG layer's sampling (issue 11): where a path-traced CG layer's frame time goes, and what
adaptive sampling, the denoiser and the bounces do to it (docs/decisions.md, "Adaptive sampling,
and the CG layer's samples").

The composite benchmark's scene (bench_composite.py: its shot, its cached 512-spp truth; `make
bench` runs that benchmark first), the default baked route (the metal path-traced, the shadows
baked once), set up once; then each row changes one setting of the CG layer and renders the shot's
last frame twice, keeping the faster. *adaptive*: off, or on with Cycles' automatic minimum
("auto") or the given minimum; *denoiser*: the compositor's OIDN on the CG where it covers the pixel
(Set Up Composite's, at the given quality), Cycles' own with albedo and normal guides ("Cycles,
guided", prefilter Fast), or none; *bounces*: the scene's, or diffuse/glossy/total caps;
*filmed phantoms* (docs/decisions.md, "Filmed phantoms"): as set up, or one part taken away: "off"
(the CG's rays path-trace the plate's albedo on the phantoms), "edge not carried" (beyond the
frame's edge path-traced), "direct unclamped" (no clamp on direct light); these rows come first,
between two controls as set up. PSNR as in
bench_composite (frame 24, peak the truth's 99.5th percentile). Timings on this 2-core machine vary
by about 15 % between identical runs.

Run: `PLATELIGHT_BENCH_SIZE=960x540 .venv/bin/python tests/bench/run_all.py --only cg_layer`
(PLATELIGHT_BENCH_CG_SCENE=glossy for another scene; a few minutes once the truths are cached)."""
from __future__ import annotations

import importlib
import os
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_composite as bc  # noqa: E402

SCENE = os.environ.get("PLATELIGHT_BENCH_CG_SCENE", "mirror")
# (CG samples, adaptive minimum: None off / 0 Cycles' automatic / n, denoiser, bounces)
ROWS = [(1, None, "none", None), (1, None, "High", None), (16, None, "High", None), (16, 4, "High", None),
        (64, None, "High", None), (64, 0, "High", None), (64, 2, "High", None), (64, 4, "High", None),
        (64, 8, "High", None), (16, None, "Fast", None), (16, None, "Balanced", None),
        (16, None, "Cycles, guided", None), (16, None, "High", (2, 2, 4)), (64, 4, "High", (2, 2, 4)),
        (256, 4, "High", None), (256, 4, "none", None)]
# the filmed phantoms with one part taken away, each at the default route's samples and settings,
# between two renders as set up (the same image twice unless a row left something changed); run
# first, on the state Set Up Composite left. (Not the plate's smoothing: a row that wrote the
# maps again unsmoothed measured no change, where fresh set-ups without it measured 0.3-0.9 dB
# less on the mirror, a difference not explained; docs/decisions.md, "Filmed phantoms")
FILMED_VARIANTS = ("off", "edge not carried", "direct unclamped")
FILMED_CONTROL = [(samples, 4, "High", None, "as set up") for samples in (16, 64)]
FILMED_ROWS = FILMED_CONTROL + [(samples, 4, "High", None, variant) for variant in FILMED_VARIANTS
                                for samples in (16, 64)] + [(256, 4, "High", None, "direct unclamped")] + FILMED_CONTROL


def ext(module):
    """The installed extension's ``module`` (e.g. "addon.names")."""
    return importlib.import_module(f"{bc.support.EXT_MODULE}.{module}")


def take_away(bpy, scene, part):
    """Take ``part`` of the filmed phantoms away; returns the function that puts it back."""
    names = ext("addon.names")
    cg_layer = scene.view_layers[names.LAYER_CG]
    if part == "off":
        cg_layer[names.FILMED_PHANTOMS_KEY] = 0.0
        return lambda: cg_layer.__setitem__(names.FILMED_PHANTOMS_KEY, 1.0)
    if part == "edge not carried":
        node = bpy.data.materials[names.PHANTOM_PLATE_MATERIAL].node_tree.nodes[
            ext("node_groups.phantom_plate").BEYOND_FRAME_NODE]
        node.inputs[0].default_value = 0.0
        return lambda: node.inputs[0].__setattr__("default_value", 1.0)
    assert part == "direct unclamped", part
    kept = scene.cycles.sample_clamp_direct
    scene.cycles.sample_clamp_direct = 0.0
    return lambda: setattr(scene.cycles, "sample_clamp_direct", kept)


def main(out_dir: pathlib.Path) -> None:
    bc.W, bc.H = (int(v) for v in bc.SIZE.split("x"))
    bpy = bc.conftest._import_bpy_with_extension()
    ext("node_groups.probe_maps").prepare_templates()
    hdri = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{bc.HDRI}.exr")
    material_name, box = bc.SHOT_SCENES[SCENE]
    material = bc.MATERIALS[material_name]
    truths, plates, plate_path = bc.shot_truths(bpy, hdri, SCENE, material, box, bc.CACHE / bc.SIZE)
    bc.build(bpy, hdri, material, bc.shot_camera(bc.SHOT_FRAMES, box), bc.BOX if box else None)
    obj, shadow = bc.masks(truths[-1], plates[-1])
    peak = float(np.percentile(truths[-1], 99.5))
    out = bc.CACHE / bc.SIZE / f"cg_layer_{SCENE.replace(' + ', '_')}"
    bc.composite_shot(bpy, hdri, material, box, "sbrdf_baked", 16, plate_path, out)
    scene = bpy.context.scene
    cycles = scene.cycles
    scene_bounces = (cycles.diffuse_bounces, cycles.glossy_bounces, cycles.max_bounces)
    names = ext("addon.names")
    cg_layer = scene.view_layers[names.LAYER_CG]
    denoise = next(n for n in bc.compat().compositor_tree(scene).nodes if n.bl_idname == "CompositorNodeDenoise"
                   and n.inputs["Image"].links and n.inputs["Image"].links[0].from_node.layer == cg_layer.name)
    rows = []
    for samples, minimum, denoiser, bounces, filmed in FILMED_ROWS + [(*row, "as set up") for row in ROWS]:
        put_back = take_away(bpy, scene, filmed) if filmed != "as set up" else (lambda: None)
        cg_layer.samples = samples
        cycles.use_adaptive_sampling = minimum is not None
        cycles.adaptive_min_samples = minimum or 0
        denoise.mute = denoiser in ("none", "Cycles, guided")
        if not denoise.mute:
            bc.compat().set_option(denoise, "Quality", denoiser)
        cycles.use_denoising = denoiser == "Cycles, guided"
        cycles.denoising_prefilter = "FAST"
        cycles.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        for layer in scene.view_layers:
            layer.cycles.use_denoising = layer == cg_layer
        cycles.diffuse_bounces, cycles.glossy_bounces, cycles.max_bounces = bounces or scene_bounces
        scene.frame_set(len(bc.RENDER_FRAMES))
        seconds = []
        for _ in range(2):
            image, took = bc.render(bpy, scene, out / "row.exr")
            seconds.append(took)
        row = dict(samples=samples, adaptive="off" if minimum is None else ("auto" if minimum == 0 else minimum),
                   denoiser=denoiser, bounces="/".join(map(str, bounces)) if bounces else "scene's", filmed=filmed,
                   warm_s=min(seconds), object=bc.psnr(image, truths[-1], obj, peak),
                   shadow=bc.psnr(image, truths[-1], shadow, peak),
                   frame=bc.psnr(image, truths[-1], np.ones_like(obj), peak))
        put_back()
        rows.append(row)
        print(row, flush=True)
    write_report(out_dir, rows)


def write_report(out_dir, rows):
    stem = f"cg_layer_{SCENE.replace(' + ', '_').replace(' ', '_')}_{bc.SIZE}"
    header = ["| CG samples | adaptive (minimum) | denoiser | bounces | filmed phantoms | warm frame (s) | PSNR object | PSNR shadow | PSNR frame |",
              "|---:|---|---|---|---|---:|---:|---:|---:|"]
    lines = [f"| {r['samples']} | {r['adaptive']} | {r['denoiser']} | {r['bounces']} | {r['filmed']} | {r['warm_s']:.2f} | "
             f"{r['object']:.2f} | {r['shadow']:.2f} | {r['frame']:.2f} |" for r in rows]
    bc.write_table(out_dir, stem, f"# The CG layer's sampling, {SCENE}, {bc.SIZE.replace('x', '×')} (issue 11)",
                   __doc__, "bench_cg_layer.py", header, lines)


if __name__ == "__main__":
    main(bc.support.REPO / "docs" / "bench")
