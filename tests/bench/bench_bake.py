"""Benchmark of probe baking (issue 4): seconds per object-frame (Cycles probe render + maps +
EXR writes) for probe sizes 64x32, 128x64, 256x128 and 4/16/64 samples, against the error of the
resulting maps versus the maps of a high-sample probe (same map sizes), and the time of a cache
hit. Writes docs/bench/bake.md and docs/bench/bake.png.

Run: `make bench` (all areas) or `.venv/bin/python tests/bench/bench_bake.py`."""
from __future__ import annotations

import os
import pathlib
import platform
import statistics
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
import support  # noqa: E402,F401
import conftest  # noqa: E402
from bake_scenes import add_plane, add_sphere, bake_module, new_scene, probe_renders  # noqa: E402

SIZES = (32, 64, 128)                 # probe heights (width is twice)
SAMPLES = (4, 16, 64)
REFERENCE = (128, 1024)               # height, samples of the reference probe
FRAMES = [1, 2, 3]
OBJECTS = ("Ball", "Mirror", "Pot")


def build_scene(bpy, folder, studio):
    """A small AR-like scene: HDRI world, grey phantom floor, three CG objects, one animated."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = new_scene(bpy, folder, env_exr=studio, save=False)
    scene.camera.location = (0, -8, 2)
    add_plane(bpy, "Floor", (0, 0, 0), size=12, color=(0.5, 0.45, 0.4), phantom=True)
    ball = add_sphere(bpy, "Ball", (0, 0, 0.6), radius=0.6, color=(0.8, 0.8, 0.8))
    add_sphere(bpy, "Mirror", (1.6, 0.5, 0.5), radius=0.5, color=(0.1, 0.6, 0.9))
    add_sphere(bpy, "Pot", (-1.5, 0.3, 0.4), radius=0.4, color=(0.9, 0.3, 0.1))
    ball.location = (0, 0, 0.6)
    ball.keyframe_insert("location", frame=1)
    ball.location = (0.4, 0.2, 0.6)
    ball.keyframe_insert("location", frame=3)
    scene.frame_set(1)
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "bench.blend"))
    return scene


def relative_rms(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()[0]
    bpy = conftest._import_bpy_with_extension()
    from platelight.addon.ibl.maps import MAP_NAMES, compute_maps

    folder = pathlib.Path(tempfile.mkdtemp(prefix="platelight-bench-bake-"))
    studio = pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / "courtyard.exr"
    scene = build_scene(bpy, folder, studio)
    module = bake_module()
    context = bpy.context
    ball = scene.objects["Ball"]
    objects = [scene.objects[n] for n in OBJECTS]

    def probe(height, samples):
        scene.platelight.probe_height, scene.platelight.probe_samples = height, samples
        # The reference keeps Cycles' own world importance map (no probe shortcut), and the
        # owner as the bake places it (by default it still casts its shadow: Owner Shadows).
        job = module.ProbeBake(context, [ball], [1], cull=False, world_map_resolution=None)
        job.start()
        try:
            scene.frame_set(1)
            owner = module.owner_visibility(ball, scene.platelight.probe_owner_shadows)
            return job.render_probe(module.probe_origin(ball), **{module.OWNER_RENDER_ARGUMENT[owner]: [ball]})
        finally:
            job.end()

    def settings_for(height):
        """The map settings a bake at this probe height uses (sizes, sampling, lobes)."""
        scene.platelight.probe_height = height
        return module.ProbeBake(context, [ball], [1]).map_settings()

    t0 = time.perf_counter()
    reference_env = probe(*REFERENCE)
    reference_seconds = time.perf_counter() - t0
    print(f"reference probe {2 * REFERENCE[0]}x{REFERENCE[0]} at {REFERENCE[1]} spp: "
          f"{reference_seconds:.1f} s", flush=True)

    rows = []
    for height in SIZES:
        ref_maps = compute_maps(reference_env, settings_for(height)).maps
        for samples in SAMPLES:
            scene.platelight.probe_height, scene.platelight.probe_samples = height, samples
            # A full multi-object, multi-frame bake, every probe rendered (force), timed whole.
            times = []
            for _ in range(2):
                t0 = time.perf_counter()
                job = module.bake_probes(context, objects, FRAMES, static=False, use_cache=False,
                                         cull=False)
                times.append((time.perf_counter() - t0) / len(job.baked))
                assert len(job.baked) == len(OBJECTS) * len(FRAMES)
                if times[-1] > 1.0:             # slow configurations: one run is enough
                    break
            per_object_frame = min(times)
            # Single object, single frame: includes the per-bake setup (camera, settings).
            single = []
            for _ in range(2):
                t0 = time.perf_counter()
                module.bake_probes(context, [ball], [1], static=True, use_cache=False, cull=False)
                single.append(time.perf_counter() - t0)
            from platelight.addon.exr_io import read_exr
            maps_dir = folder / "platelight_maps" / "Ball"
            errors = {n: relative_rms(read_exr(maps_dir / f"{n}.exr"), ref_maps[n]) for n in MAP_NAMES}
            rows.append((height, samples, per_object_frame, min(single), errors))
            print(f"{2 * height}x{height} {samples:3d} spp: {per_object_frame * 1e3:7.1f} ms/object-frame, "
                  f"single {min(single) * 1e3:7.1f} ms, " +
                  " ".join(f"{n} {e * 100:.2f}%" for n, e in errors.items()), flush=True)

    # The world importance-map cap: a single bake with Cycles' own setting versus the probe cap.
    scene.platelight.probe_height, scene.platelight.probe_samples = 64, 16
    importance = {}
    for label, limit in (("Cycles' own (1024 columns)", None),
                         (f"probe cap ({bake_module('probe_render').PROBE_WORLD_MAP_RESOLUTION} columns)",
                          bake_module("probe_render").PROBE_WORLD_MAP_RESOLUTION)):
        runs = []
        for _ in range(2):
            job = module.ProbeBake(context, [ball], [1], use_cache=False, cull=False,
                                   world_map_resolution=limit)
            t0 = time.perf_counter()
            try:
                job.start()
                while job.step():
                    pass
            finally:
                job.end()
            runs.append(time.perf_counter() - t0)
        maps_dir = folder / "platelight_maps" / "Ball"
        from platelight.addon.exr_io import read_exr
        ref_maps = compute_maps(reference_env, settings_for(64)).maps
        importance[label] = (min(runs), {n: relative_rms(read_exr(maps_dir / f"{n}.exr"), ref_maps[n])
                                         for n in MAP_NAMES})
        print(f"single bake 128x64 16 spp, world importance map {label}: {min(runs):.3f} s", flush=True)

    # Cache hits: nothing changed since the last bake.
    scene.platelight.probe_height, scene.platelight.probe_samples = 64, 16
    module.bake_probes(context, objects, [1], static=True, cull=False)
    before = probe_renders()
    hit_one, hit_three = [], []
    for _ in range(30):
        t0 = time.perf_counter()
        module.bake_probes(context, [ball], [1], static=True, cull=False)
        hit_one.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        module.bake_probes(context, objects, [1], static=True, cull=False)
        hit_three.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    result = bpy.ops.platelight.bake_probes(all_objects=True, cull=False)
    hit_operator = time.perf_counter() - t0
    assert probe_renders() == before and result == {"FINISHED"}, "cache hits rendered"
    hits = {"one object (bake_probes)": statistics.median(hit_one),
            "three objects (bake_probes)": statistics.median(hit_three),
            "three objects (bpy.ops operator, incl. undo push)": hit_operator}
    for k, v in hits.items():
        print(f"cache hit, {k}: {v * 1e3:.2f} ms", flush=True)

    load = (load_before, os.getloadavg()[0])
    write_report(out_dir, rows, hits, reference_seconds, load, importance)


def write_report(out_dir, rows, hits, reference_seconds, load, importance):
    import bpy
    import matplotlib

    from platelight.addon.bake.probe_size import samples_for

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from platelight.addon.ibl.maps import MAP_NAMES

    version = bpy.app.version_string
    lines = [
        "# Probe baking benchmark (issue 4)",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPU cores (shared), "
        f"Cycles on CPU, Blender {version} as a Python module. Generated by `tests/bench/bench_bake.py`. "
        f"Load average at start / end: {load[0]:.1f} / {load[1]:.1f} (other people's jobs share the "
        "cores: times scale with it).",
        "",
        "Scene: courtyard HDRI world, a grey phantom floor, three CG spheres (one animated). "
        f"**Per object-frame**: a bake of {len(OBJECTS)} objects x {len(FRAMES)} frames, every probe "
        "rendered (cache off), wall time / 9: frame change, the owner made shadow-only, Cycles renders "
        "of the panorama and its distance map, EXR read-back, the four maps (`compute_maps`, exact "
        "mode), the view-dependent ladder's rungs, the irradiance grid (64 points), the EXR writes and "
        "the bake record. The first probe of each bake also builds the world's light-importance map "
        "(about 1 s under this 2k HDRI; see the second table). **Single**: one object, one frame, including the bake's setup and teardown. "
        f"**Error**: relative RMS of each map against the maps of a {2 * REFERENCE[0]}x{REFERENCE[0]} "
        f"probe rendered with {REFERENCE[1]} samples ({reference_seconds:.1f} s; the owner shadow-only, as the bake "
        "places it), at the same map "
        "sizes (maps are capped at the probe's height), for object Ball at frame 1.",
        "",
        "**Probe Samples** is the setting; a probe under 128 rows renders with more "
        "(`addon/bake/probe_size.samples_for`: up to 2x), shown as **rendered spp**.",
        "",
        "| probe | Probe Samples | rendered spp | s / object-frame | single bake (s) | "
        + " | ".join(f"{n} error" for n in MAP_NAMES) + " |",
        "|---|---|---|---|---|" + "---|" * len(MAP_NAMES),
    ]
    for height, samples, per, single, errors in rows:
        lines.append(f"| {2 * height}x{height} | {samples} | {samples_for(samples, height)} | {per:.3f} | {single:.3f} | " +
                     " | ".join(f"{errors[n] * 100:.2f} %" for n in MAP_NAMES) + " |")
    target = [r for r in rows if r[0] == 64]
    lines += ["", "Target: <= 0.5 s per object-frame at 128x64: "
              + ", ".join(f"Probe Samples {r[1]} {r[2]:.3f} s" for r in target) + ".", "",
              "| single bake 128x64, Probe Samples 16 (32 rendered): world importance map | s | " +
              " | ".join(f"{n} error" for n in MAP_NAMES) + " |", "|---|---|" + "---|" * len(MAP_NAMES)]
    for label, (seconds, errors) in importance.items():
        lines.append(f"| {label} | {seconds:.3f} | " +
                     " | ".join(f"{errors[n] * 100:.2f} %" for n in MAP_NAMES) + " |")
    lines += ["", "| cache hit (nothing changed, no render) | ms |", "|---|---|"]
    for k, v in hits.items():
        lines.append(f"| {k} | {v * 1e3:.2f} |")
    lines += ["", "Target: cache hit <= 10 ms.", "", "![time vs error](bake.png)", ""]
    (out_dir / "bake.md").write_text("\n".join(lines))

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, name in zip(axes, ("diffuse", "specular")):
        for height in SIZES:
            pts = [(r[2], r[4][name]) for r in rows if r[0] == height]
            ax.plot([p[0] for p in pts], [p[1] * 100 for p in pts], "o-", label=f"{2 * height}x{height}")
            for (x, y), s in zip(pts, SAMPLES):
                ax.annotate(f"{s}", (x, y * 100), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.axvline(0.5, color="grey", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("seconds per object-frame (labels: samples)")
        ax.set_ylabel(f"{name} map relative RMS error (%)")
        ax.set_title(f"{name} map vs {REFERENCE[1]}-sample probe")
        ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "bake.png", dpi=110)


if __name__ == "__main__":
    main(pathlib.Path(__file__).resolve().parents[2] / "docs" / "bench")
