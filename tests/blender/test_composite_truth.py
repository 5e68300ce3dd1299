"""Ground truth, small: a diffuse sphere composited onto a path-traced plate against the same
scene path-traced with the sphere really there (the benchmark's scene at 64×36)."""
import importlib.util

import numpy as np

import support


def bench_module():
    path = support.REPO / "tests" / "bench" / "bench_composite.py"
    spec = importlib.util.spec_from_file_location("bench_composite_for_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.W, module.H = 64, 36
    return module


def path_traced(bpy, bench, hdri, material, samples, folder):
    """The truth (sphere there) and the plate (sphere absent), path-traced, no denoiser; the plate
    is written to folder/plate.exr."""
    renders = {}
    for name, with_sphere in (("truth", True), ("plate", False)):
        scene, floor, sphere = bench.build(bpy, hdri, material)
        scene.cycles.samples = samples
        scene.cycles.use_denoising = False
        sphere.hide_render = not with_sphere
        renders[name], _ = bench.render(bpy, scene, folder / f"{name}.exr")
    return renders["truth"], renders["plate"]


def test_composite_matches_path_traced_truth(bpy_clean, tmp_path, studio_hdris):
    bpy = bpy_clean
    bench = bench_module()
    hdri = str(studio_hdris["city"])
    material = bench.MATERIALS["diffuse"]
    truth, plate = path_traced(bpy, bench, hdri, material, 256, tmp_path)
    composite, _, _ = bench.composite(bpy, hdri, material, tmp_path / "plate.exr", "cycles", 64,
                                   tmp_path / "composite.exr")
    obj, shadow = bench.masks(truth, plate)
    assert obj.sum() > 30 and shadow.sum() > 30
    peak = float(np.percentile(truth, 99.5))
    assert bench.psnr(composite, truth, obj, peak) > 30      # measured 33.6 dB (truth's own noise)
    assert bench.psnr(composite, truth, shadow, peak) > 35   # measured 40.4 dB
    # the shadow really was added: the composite is much closer to the truth there than the plate
    err_plate = np.abs(plate - truth)[shadow].mean()
    err_comp = np.abs(composite - truth)[shadow].mean()
    assert err_comp < 0.15 * err_plate  # measured 0.07


def test_sbrdf_mirror_is_closer_to_path_tracing_than_the_papers_model(bpy_clean, tmp_path, studio_hdris):
    """The SBRDF's defaults (no cosine falloff, layered diffuse, owner shadows in its probe)
    against the paper's model as written, on the benchmark's mirror sphere: both shaded from
    their own 64-spp probes, compared with the sphere path-traced in place."""
    bpy = bpy_clean
    bench = bench_module()
    hdri = str(studio_hdris["city"])
    material = bench.MATERIALS["mirror"]
    truth, plate = path_traced(bpy, bench, hdri, material, 128, tmp_path)
    obj, _ = bench.masks(truth, plate)
    peak = float(np.percentile(truth, 99.5))
    psnr = {}
    # the SBRDF pinned (a metal's default in Cycles is its path-traced twin)
    for route in ("sbrdf_sbrdf", "sbrdf_paper"):
        image, bake_s, _ = bench.composite(bpy, hdri, material, tmp_path / "plate.exr", route, 4,
                                           tmp_path / f"{route}.exr")
        assert bake_s > 0
        psnr[route] = bench.psnr(image, truth, obj, peak)
    # measured at 64x36: 26.0 dB against 20.4 dB (the paper's cosine darkens the whole rim)
    assert psnr["sbrdf_sbrdf"] > 24 and psnr["sbrdf_sbrdf"] > psnr["sbrdf_paper"] + 4, psnr
