"""Benchmark of what phantoms show (issue 12): the camera-projected plate (default) against the
phantom's hand-made material (the paper's phantoms), on bench_composite's scene: a sphere
(diffuse, mirror, glossy) on a grey floor under the bundled `city` HDRI, path-traced truth with
the sphere present, the plate without it, Cycles' shadow-catcher composite. The hand-made floor
material here is the truth's own (grey 0.45 diffuse), the best case for hand-made phantoms: the
plate route has to match it without being told the floor's material.

Writes docs/bench/phantom_surface.md. Run: `make bench` or
`.venv/bin/python tests/bench/bench_phantom_surface.py`.
"""
from __future__ import annotations

import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
import bench_composite as bc  # noqa: E402
import conftest  # noqa: E402

SAMPLES = (16, 64)
SURFACES = ("PLATE", "MATERIAL")


def composite(bpy, hdri_path, material, plate_path, surface, samples, out_path):
    scene, floor, sphere = bc.build(bpy, hdri_path, material)
    floor.platelight.phantom = True
    scene.platelight.phantom_surface = surface
    t0 = time.perf_counter()
    assert bpy.ops.platelight.setup_plate(filepath=str(plate_path)) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=samples, denoise_shadows=True) == {"FINISHED"}
    image, _ = bc.render(bpy, scene, out_path)
    return image, time.perf_counter() - t0


def main(out_dir: pathlib.Path) -> None:
    bpy = conftest._import_bpy_with_extension()
    hdri_path = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{bc.HDRI}.exr")
    rows = []
    for name, material in bc.MATERIALS.items():
        truth, plate, plate_path, _ = bc.truth_and_plate(bpy, hdri_path, name, material)
        bc.build(bpy, hdri_path, material)
        obj, shadow = bc.masks(truth, plate)
        peak = float(bc.np.percentile(truth, 99.5))
        for surface in SURFACES:
            for samples in SAMPLES:
                image, seconds = composite(bpy, hdri_path, material, plate_path, surface, samples,
                                           bc.CACHE / f"phantom_{name}_{surface}_{samples}.exr")
                rows.append(dict(material=name, surface=surface, samples=samples, seconds=seconds,
                                 psnr_object=bc.psnr(image, truth, obj, peak),
                                 psnr_shadow=bc.psnr(image, truth, shadow, peak),
                                 psnr_all=bc.psnr(image, truth, bc.np.ones_like(obj), peak)))
                print(rows[-1], flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Phantom surface benchmark (issue 12)", "",
        f"bench_composite's scene ({bc.W}×{bc.H}, `{bc.HDRI}` HDRI, truth {bc.TRUTH_SAMPLES} spp), Cycles "
        "shadow catcher with OIDN. *PLATE*: the floor phantom shows the camera-projected plate to "
        "reflections and bounced light (default); *MATERIAL*: its hand-made material, here exactly "
        "the truth's floor material (the best case for hand-made phantoms). PSNR in dB (peak = the "
        "truth's 99.5th percentile) over the sphere, its shadow, the frame; seconds for set-up + "
        "render of one frame on the shared 2-core machine. Produced by "
        "`tests/bench/bench_phantom_surface.py`.", "",
        "| material | phantom surface | spp | s | PSNR object | PSNR shadow | PSNR frame |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['material']} | {r['surface']} | {r['samples']} | {r['seconds']:.2f} | "
                     f"{r['psnr_object']:.1f} | {r['psnr_shadow']:.1f} | {r['psnr_all']:.1f} |")
    (out_dir / "phantom_surface.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(HERE.parents[1] / "docs" / "bench")
