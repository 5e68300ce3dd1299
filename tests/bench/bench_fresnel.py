"""A dielectric's Fresnel, converted from Principled (addon/material/principled.py): the fitted
Fresnel Peak and head-on factor against the single exponent with the paper's peak of 1.

Two measures for Principled plastics (IOR 1.5, Cycles' default multiscatter GGX):
- the specular weight rho_s + (1 - rho_s) c (1 - cos)^k the SBRDF gives against the layer's
  directional albedo E(cos) computed by brute force (tests/test_material.py's visible-normal
  quadrature with Cycles' energy compensation), max error over cos in [0.1, 1];
- the composite benchmark's shot (tests/bench/bench_composite.py: 480x270, sphere on a phantom
  floor under `city`, the default route at 4 samples, frame 24 scored) with a red plastic sphere,
  object PSNR against a 256-spp path-traced truth.

Run: `.venv/bin/python tests/bench/run_all.py --only fresnel` (about 8 minutes on 2 cores);
writes docs/bench/fresnel.md."""
from __future__ import annotations

import os
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))
import bench_composite as bc  # noqa: E402
import test_material  # noqa: E402

ROUGHNESS = (0.3, 0.5, 1.0)
COLOUR = (0.6, 0.12, 0.1)
SIZE = (480, 270)
SAMPLES = 4
TRUTH_SAMPLES = 256


def paper_terms(principled):
    """The conversion before the Fresnel Peak: one exponent fitted to the normalised rise, c = 1,
    F0 as is."""
    return lambda roughness, metallic: (principled.roughness_to_fresnel_falloff(roughness), 1.0, 1.0)


def weight_error(principled, roughness):
    """Max |specular weight - albedo| over cos 0.1..1 of a plastic converted by ``principled``."""
    mus = np.linspace(0.1, 1.0, 46)
    albedo = np.array([test_material._multiscatter_albedo(mu, max(roughness ** 2, 1e-4)) for mu in mus])
    converted = principled.principled_to_sbrdf(principled.PrincipledValues(roughness=roughness))
    return float(np.abs(test_material._specular_weight(converted, mus) - albedo).max())


def converters():
    """Every loaded copy of the conversion module (the extension's and the test package's)."""
    return [m for name, m in sys.modules.items() if name.endswith("addon.material.principled")]


def main(out_dir: pathlib.Path) -> None:
    bc.W, bc.H = SIZE
    bc.TRUTH_SAMPLES = TRUTH_SAMPLES
    bpy = bc.conftest._import_bpy_with_extension()
    modules = converters()
    fitted = {m: m.fresnel_terms for m in modules}
    hdri = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{bc.HDRI}.exr")
    rows = []
    for roughness in ROUGHNESS:
        material = dict(colour=COLOUR, roughness=roughness, metallic=0.0)
        folder = bc.CACHE / f"{SIZE[0]}x{SIZE[1]}_plastic_{roughness}"
        truths, plates, plate_path = bc.shot_truths(bpy, hdri, "plastic", material, False, folder)
        for mode in ("paper", "fitted"):
            for m in modules:
                m.fresnel_terms = fitted[m] if mode == "fitted" else paper_terms(m)
            error = weight_error(modules[0], roughness)
            t0 = time.perf_counter()
            images, *_ = bc.composite_shot(bpy, hdri, material, False, "sbrdf", SAMPLES, plate_path,
                                           folder / f"sbrdf_{mode}")
            seconds = time.perf_counter() - t0
            bc.build(bpy, hdri, material, bc.shot_camera(bc.SCORED_FRAMES[0], False), None)
            obj, _shadow = bc.masks(truths[0], plates[0])
            peak = float(np.percentile(truths[0].ravel(), 99.5))
            scored = [image for image, frame in zip(images, bc.RENDER_FRAMES) if frame in bc.SCORED_FRAMES]
            rows.append(dict(roughness=roughness, mode=mode, weight_error=error, seconds=seconds,
                             psnr=bc.pooled_psnr(scored, truths, [obj], peak)))
            print(rows[-1], flush=True)
    for m in modules:
        m.fresnel_terms = fitted[m]
    write_report(out_dir, rows)


def write_report(out_dir, rows):
    lines = ["# A dielectric's Fresnel: fitted peak against the paper's", "",
             "Principled plastics (IOR 1.5, Cycles' default multiscatter GGX), converted to the SBRDF "
             "two ways, measured two ways (`tests/bench/bench_fresnel.py`):", "",
             "- *max weight error*: the SBRDF's specular weight rho_s + (1 - rho_s) c (1 - cos)^k "
             "against the layer's directional albedo E(cos) by brute force (tests/test_material.py's "
             "visible-normal quadrature with Cycles' energy compensation), over cos in [0.1, 1];",
             "- *object PSNR*: the composite benchmark's shot (tests/bench/bench_composite.py: "
             f"{SIZE[0]}x{SIZE[1]}, a sphere on a phantom floor under `{bc.HDRI}`, the default route at "
             f"{SAMPLES} samples, frame {bc.SCORED_FRAMES[0]} scored) with a plastic sphere of colour "
             f"{COLOUR}, against a {TRUTH_SAMPLES}-spp path-traced truth.", "",
             "*paper*: f = (1 - cos)^k reaching 1 at grazing, k fitted to the albedo's normalised "
             "rise, rho_s = F0. *fitted*: f = c (1 - cos)^k with the "
             "Fresnel Peak c and k fitted together, rho_s = E(1) (the default). Time: the shot's "
             "set-up, bake and two frames (the same work both ways).",
             "", "| roughness | conversion | max weight error | object PSNR (dB) | s |",
             "|---:|---|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['roughness']:.1f} | {r['mode']} | {r['weight_error']:.4f} | {r['psnr']:.2f} | {r['seconds']:.1f} |")
    note = os.environ.get("PLATELIGHT_BENCH_LOAD_NOTE", "")
    if note:
        lines += ["", note]
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "fresnel.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(HERE.parents[1] / "docs" / "bench")
