"""Benchmark of AR compositing (issue 6) against path-traced ground truth.

A sphere (diffuse, mirror, glossy) on a grey floor under a real probe (the bundled 'city' HDRI,
with a sun). The truth: Cycles path-traces the sphere on the floor at high samples (the "filmed"
footage with the object really there). The plate: the same without the sphere. Then the sphere
is composited onto the plate with the floor as a phantom by
  - PlateLight: lights from the probe (sun + 16 median-cut lights) light the floor's shadow,
    the CG sees the world in reflections, Cycles shadow-catcher composite, N samples, OIDN;
  - Cycles' own route: the world lights everything, shadow catcher, N samples, OIDN.
PSNR against the truth over the object and over the shadowed floor separately (masks from the
analytic sphere and from the truth's own shadow), and total time (lights + render + composite).
Writes docs/bench/composite.md and docs/bench/composite.png.

Run: `make bench` or `.venv/bin/python tests/bench/bench_composite.py`.
"""
from __future__ import annotations

import math
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import support  # noqa: E402
import conftest  # noqa: E402
from platelight.addon.exr_io import read_exr  # noqa: E402

W, H = 128, 72
TRUTH_SAMPLES = 512
HDRI = "city"
CACHE = support.REPO / "bench_out" / "composite"
MATERIALS = {
    "diffuse": dict(colour=(0.7, 0.7, 0.7), roughness=1.0, metallic=0.0),
    "mirror": dict(colour=(0.9, 0.9, 0.9), roughness=0.0, metallic=1.0),
    "glossy": dict(colour=(0.8, 0.5, 0.3), roughness=0.3, metallic=1.0),
}
ROUTES = (("platelight sbrdf", (1, 4, 16)), ("platelight lamps", (4, 16, 64)),
          ("platelight sun+sky", (4, 16, 64)), ("cycles catcher", (4, 16, 64, 192)))
ROUTE_KEYS = {"platelight sbrdf": "sbrdf", "platelight lamps": "lamps", "platelight sun+sky": "sunsky",
              "cycles catcher": "cycles"}
PROBE_SAMPLES = 64
SPHERE = (np.array([0.0, 0.0, 0.5]), 0.5)


def build(bpy, hdri_path, material):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 7
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("Probe")
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    scene.world = world
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (-2.2, -4.6, 2.2)
    from mathutils import Vector

    cam.rotation_euler = Vector((1.9, 4.9, -1.9)).to_track_quat("-Z", "Y").to_euler()
    floor_mat = bpy.data.materials.new("Floor")
    floor_mat.node_tree.nodes.clear()
    diffuse = floor_mat.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.45, 0.45, 0.45, 1)
    out = floor_mat.node_tree.nodes.new("ShaderNodeOutputMaterial")
    floor_mat.node_tree.links.new(diffuse.outputs[0], out.inputs["Surface"])
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(floor_mat)
    floor = bpy.data.objects.new("Floor", mesh)
    scene.collection.objects.link(floor)
    import bmesh

    smesh = bpy.data.meshes.new("Sphere")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=96, v_segments=48, radius=SPHERE[1])
    bm.to_mesh(smesh)
    bm.free()
    for poly in smesh.polygons:
        poly.use_smooth = True
    mat = bpy.data.materials.new("Sphere")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*material["colour"], 1)
    bsdf.inputs["Roughness"].default_value = material["roughness"]
    bsdf.inputs["Metallic"].default_value = material["metallic"]
    smesh.materials.append(mat)
    sphere = bpy.data.objects.new("Sphere", smesh)
    sphere.location = tuple(SPHERE[0])
    scene.collection.objects.link(sphere)
    return scene, floor, sphere


def render(bpy, scene, path):
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return read_exr(path), time.perf_counter() - t0


def truth_and_plate(bpy, hdri_path, name, material):
    """The path-traced truth (sphere present) and plate (sphere absent), cached on disk."""
    CACHE.mkdir(parents=True, exist_ok=True)
    truth_path = CACHE / f"truth_{name}_{TRUTH_SAMPLES}.exr"
    plate_path = CACHE / f"plate_{TRUTH_SAMPLES}.exr"
    times = {}
    if not truth_path.exists():
        scene, floor, sphere = build(bpy, hdri_path, material)
        scene.cycles.samples = TRUTH_SAMPLES
        scene.cycles.use_denoising = False
        _, times["truth_s"] = render(bpy, scene, truth_path)
    if not plate_path.exists():
        scene, floor, sphere = build(bpy, hdri_path, material)
        scene.cycles.samples = TRUTH_SAMPLES
        scene.cycles.use_denoising = False
        sphere.hide_render = True
        _, times["plate_s"] = render(bpy, scene, plate_path)
    return read_exr(truth_path), read_exr(plate_path), plate_path, times


def composite(bpy, hdri_path, material, plate_path, route, samples, out_path):
    scene, floor, sphere = build(bpy, hdri_path, material)
    floor.platelight.phantom = True
    t0 = time.perf_counter()
    if route == "lamps":
        scene.platelight.world_probe = hdri_path
        assert bpy.ops.platelight.lights_from_probe(mode="LIGHTS", count=16) == {"FINISHED"}
    elif route == "sunsky":
        assert bpy.ops.platelight.lights_from_probe(mode="SUN_SKY") == {"FINISHED"}
    elif route == "sbrdf":
        sbrdf_sphere(bpy, scene, sphere, out_path)
    assert bpy.ops.platelight.setup_plate(filepath=str(plate_path)) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=samples, denoise_shadows=True) == {"FINISHED"}
    setup = time.perf_counter() - t0
    image, render_time = render(bpy, scene, out_path)
    return image, setup + render_time


def sbrdf_sphere(bpy, scene, sphere, out_path):
    """The paper's CG: the sphere's Principled settings converted to the PlateLight SBRDF, shaded
    from its own probe (baked from its centre: floor + world)."""
    from platelight.addon.demo_ar import _bake_probes

    scene.platelight.maps_dir = str(pathlib.Path(out_path).with_suffix("")) + "_probes"
    scene.platelight.probe_samples = PROBE_SAMPLES
    sphere.platelight.enabled = True
    bpy.context.view_layer.objects.active = sphere
    sphere.select_set(True)
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    _bake_probes(bpy, [sphere], force=True)  # with the world's full importance map (see demo_ar)


def psnr(a, b, mask, peak):
    err = np.mean((np.clip(a, 0, peak) - np.clip(b, 0, peak))[mask] ** 2)
    return float(10 * np.log10(peak ** 2 / max(err, 1e-20)))


def masks(truth, plate):
    """object: pixels whose centre ray meets the sphere (analytic, eroded a pixel);
    shadow: floor pixels the truth shows more than 3 % darker than the plate."""
    import cv2
    import bpy

    scene = bpy.context.scene
    bpy.context.view_layer.update()  # matrix_world of a camera just placed
    cam = scene.camera
    tr, br, bl, tl = (np.array(cam.matrix_world @ v) for v in cam.data.view_frame(scene=scene))
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    top = tl + u[:, None] * (tr - tl)
    bottom = bl + u[:, None] * (br - bl)
    pts = top[None] + v[:, None, None] * (bottom - top)[None]
    origin = np.array(cam.matrix_world.translation)
    d = pts - origin
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    oc = origin - SPHERE[0]
    b = d @ oc
    hit = b * b - (oc @ oc - SPHERE[1] ** 2) >= 0
    obj = cv2.erode(hit.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    near = cv2.dilate(hit.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    lum = np.array([0.2126, 0.7152, 0.0722])
    darker = (truth @ lum) < 0.97 * (plate @ lum)
    shadow = darker & ~near
    return obj, shadow


def main(out_dir: pathlib.Path) -> None:
    bpy = conftest._import_bpy_with_extension()
    hdri_path = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{HDRI}.exr")
    rows = []
    for name, material in MATERIALS.items():
        truth, plate, plate_path, ref_times = truth_and_plate(bpy, hdri_path, name, material)
        build(bpy, hdri_path, material)  # for the camera used by the masks
        obj, shadow = masks(truth, plate)
        peak = float(np.percentile(truth, 99.5))
        for route, sample_counts in ROUTES:
            for samples in sample_counts:
                key = ROUTE_KEYS[route]
                image, seconds = composite(bpy, hdri_path, material, plate_path, key, samples,
                                           CACHE / f"comp_{name}_{key}_{samples}.exr")
                rows.append(dict(material=name, route=route, samples=samples, seconds=seconds,
                                 psnr_object=psnr(image, truth, obj, peak),
                                 psnr_shadow=psnr(image, truth, shadow, peak),
                                 psnr_all=psnr(image, truth, np.ones_like(obj), peak),
                                 shadow_px=int(shadow.sum()), object_px=int(obj.sum())))
                print(rows[-1], flush=True)
    write_report(out_dir, rows)


def write_report(out_dir, rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Compositing benchmark (issue 6)",
        "",
        f"Sphere on a grey floor under the bundled `{HDRI}` HDRI, {W}×{H}. Truth: Cycles path-traced with "
        f"the sphere present, {TRUTH_SAMPLES} spp (no denoiser); plate: the same without the sphere. "
        "Composites onto that plate with the floor as a phantom (shadow catcher), OIDN on the CG and "
        "the shadow pass. *platelight lamps*: floor and CG lit by the probe's lamps (sun + 16 "
        "median-cut, `lights_from_probe(mode='LIGHTS')`), the world only in reflections; "
        "*platelight sun+sky*: the probe's sun moved into a sharp sun lamp, the world shows the "
        "sun-less probe (`lights_from_probe(mode='SUN_SKY')`); *cycles catcher*: the world "
        "(with its sun) lights everything and the CG is path-traced Principled. *platelight sbrdf*: "
        "the CG is the PlateLight SBRDF (the Principled settings converted by `apply_sbrdf`) shaded "
        "from its own probe (the bake's `ProbeBake`, default 128×64 probe, 64 spp, the world's full importance map; the bake is in the time), "
        "the floor's shadow as in *cycles catcher*. PSNR (dB, peak = the truth's 99.5th percentile) over the sphere, "
        "over the truth's shadow on the floor (>3 % darker than the plate), and over the frame. "
        "Time: lights + set-up + render + composite, on this 2-core machine shared with other jobs "
        "(so only comparable within one run). Produced by `tests/bench/bench_composite.py`.",
        "",
        "| material | route | spp | time (s) | PSNR object | PSNR shadow | PSNR frame |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['material']} | {r['route']} | {r['samples']} | {r['seconds']:.2f} | "
                     f"{r['psnr_object']:.1f} | {r['psnr_shadow']:.1f} | {r['psnr_all']:.1f} |")
    if rows:
        lines += ["", f"Mask sizes: object {rows[0]['object_px']} px, shadow {rows[0]['shadow_px']} px "
                  "(first material; see the CSV-like table above for all)."]
    (out_dir / "composite.md").write_text("\n".join(lines) + "\n")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, title in ((axes[0], "psnr_object", "object"), (axes[1], "psnr_shadow", "shadowed floor")):
        for material, marker in zip(MATERIALS, "osD"):
            for route, colour in zip(ROUTE_KEYS, ("tab:red", "tab:orange", "tab:green", "tab:blue")):
                pts = [(r["seconds"], r[key]) for r in rows if r["material"] == material and r["route"] == route]
                if pts:
                    xs, ys = zip(*pts)
                    ax.plot(xs, ys, marker=marker, color=colour, label=f"{route}, {material}")
        ax.set_xscale("log")
        ax.set_xlabel("time per frame (s)")
        ax.set_ylabel("PSNR vs path-traced truth (dB)")
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "composite.png", dpi=110)


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
