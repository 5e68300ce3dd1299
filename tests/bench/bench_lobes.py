"""How well four blurred maps stand for a glossy metal's GGX lobe (issue 11: the glossy sphere's
object PSNR). numpy only, no Blender.

A metal sphere (no Fresnel or albedo: the lobe's shape alone) seen from three directions under a
bundled HDRI. Truth: for every pixel, the radiance integrated over the probe's texels (256 rows)
with Cycles' GGX microfacet lobe (D, height-correlated Smith G2; tests/reference.py) at that pixel's view, over the
whole hemisphere above the surface. PlateLight: the maps blended by design.md's glossiness rule at the
roughness's glossiness (addon/material/principled.py), with the glossy maps blurred by the paper's
Phong lobes or by GGX's (MapSettings.lobes), looked up along the mirror direction R (the paper) or
along R tilted towards the normal (the look-up tilt, addon/ibl/lobe_tilt.py: the shader's default).
PSNR over the sphere's pixels, peak = the HDRI's 90th percentile by solid angle
(`display_peak`: about the brightness a composite frame of that place clips at, docs/bench/composite.md's
peak; not the sphere's own 99.5th percentile, which a sun's highlight raises, inflating the scores by
up to 20 dB).

Run: `.venv/bin/python tests/bench/bench_lobes.py` (about 3 minutes on 2 cores); writes
docs/bench/lobes.md."""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
import reference  # noqa: E402
import support  # noqa: E402,F401
from platelight.addon.demo import bundled_hdris  # noqa: E402
from platelight.addon.exr_io import read_exr  # noqa: E402
from platelight.addon.ibl import lobe_tilt, maps  # noqa: E402
from platelight.addon.material.principled import roughness_to_glossiness  # noqa: E402

HDRIS = ("city", "courtyard", "sunset")
ROUGHNESS = (0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6)
VIEW_AZIMUTHS = (0.0, 120.0, 240.0)
PIXELS = 24                    # the sphere's diameter in pixels
TRUTH_HEIGHT = 256
DISPLAY_PERCENTILE = 90.0      # display_peak
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def sphere_view(azimuth, elevation=15.0, pixels=PIXELS):
    """Normals and the (constant) view direction of an orthographic sphere ``pixels`` across."""
    e, a = np.radians(elevation), np.radians(azimuth)
    view = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.cross([0.0, 0.0, 1.0], view)
    right /= np.linalg.norm(right)
    up = np.cross(view, right)
    xs = (np.arange(pixels) + 0.5) / pixels * 2 - 1
    x, y = np.meshgrid(xs, -xs)
    inside = x ** 2 + y ** 2 < 0.995
    x, y = x[inside], y[inside]
    z = np.sqrt(1 - x * x - y * y)
    return x[:, None] * right + y[:, None] * up + z[:, None] * view, view


def lookups(normals, view, glossiness, tilt):
    """The maps' look-up directions: the mirror direction, tilted towards N with ``tilt``."""
    reflected = 2 * (normals @ view)[:, None] * normals - view
    return lobe_tilt.tilted(reflected, normals, glossiness) if tilt else reflected


def display_peak(env) -> float:
    """The luminance a composite frame under ``env`` clips at: the HDRI's 90th percentile by solid
    angle. docs/bench/composite.md's peak, the frame's 99.5th percentile, is set by the plate's sky
    and floor: 1.65 under city, whose 90th percentile is 1.8 (its 99.5th, 5.2, is the glow around
    the sun). A bare sphere's own 99.5th percentile sits in a white metal's sun highlight, tens of
    times the sky, and scored the errors against that: up to 20 dB too kind."""
    _, solid = reference.texel_grid(env.shape[0])
    lum = np.asarray(env, dtype=np.float64).reshape(-1, env.shape[-1])[:, :3] @ LUMINANCE
    order = np.argsort(lum)
    cumulative = np.cumsum(solid[order]) / solid.sum()
    return float(lum[order][np.searchsorted(cumulative, DISPLAY_PERCENTILE / 100)])


def psnr(image, truth, peak):
    """Luminance PSNR, both images clipped at ``peak`` (display_peak) as bench_composite.psnr clips."""
    lum_image, lum_truth = image @ LUMINANCE, truth @ LUMINANCE
    error = np.clip(lum_image, 0, peak) - np.clip(lum_truth, 0, peak)
    return float(10 * np.log10(peak ** 2 / np.mean(error ** 2)))


def gain_summary(gains) -> str:
    """A benchmark report's summary of per-row gains (dB): their mean and range."""
    gains = np.asarray(gains)
    return f"{gains.mean():+.2f} dB (range {gains.min():+.2f} to {gains.max():+.2f})"


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    views = [sphere_view(a) for a in VIEW_AZIMUTHS]
    rows = []
    for name in HDRIS:
        env = np.maximum(read_exr(bundled_hdris()[name]), 0).astype(np.float32)
        peak = display_peak(env)
        lobe_maps = {lobes: maps.compute_maps(env, maps.MapSettings(lobes=lobes)).maps
                     for lobes in maps.LOBES}
        for roughness in ROUGHNESS:
            t0 = time.perf_counter()
            alpha = roughness ** 2
            truths = [reference.anisotropic_ggx(env, alpha, alpha, normals, reference.tangents_about_z(normals),
                                                view, TRUTH_HEIGHT) for normals, view in views]
            glossiness = roughness_to_glossiness(roughness)
            scores = {}
            for lobes, found in lobe_maps.items():
                for tilt in (False, True):
                    scores[(lobes, tilt)] = float(np.mean([
                        psnr(maps.blended_lookup(found, glossiness, lookups(normals, view, glossiness, tilt)), t, peak)
                        for (normals, view), t in zip(views, truths)]))
            rows.append((name, roughness, glossiness, scores))
            print(f"{name:10s} r {roughness:.2f}  " + "  ".join(f"{k}{' tilted' * t} {v:6.2f} dB"
                                                                for (k, t), v in scores.items())
                  + f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    write_report(out_dir / "lobes.md", rows)


def write_report(path, rows):
    lines = [
        "# Glossy lobes: four blurred maps against GGX (issue 11)", "",
        (__doc__.split("\n\n")[1].replace("\n", " ")), "",
        "Produced by `tests/bench/bench_lobes.py`.", "",
        "| HDRI | roughness | glossiness | Phong, R (dB) | GGX, R | Phong, tilted (default) | GGX, tilted |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, roughness, glossiness, scores in rows:
        lines.append(f"| {name} | {roughness:.2f} | {glossiness:.3f} | {scores[('phong', False)]:.2f} | "
                     f"{scores[('ggx', False)]:.2f} | {scores[('phong', True)]:.2f} | "
                     f"{scores[('ggx', True)]:.2f} |")

    def mean_gain(a, b):
        return gain_summary([s[a] - s[b] for *_, s in rows])
    lines += ["", "Mean gain over all rows: GGX lobes over Phong, along R: "
              f"{mean_gain(('ggx', False), ('phong', False))}; the tilt, Phong lobes: "
              f"{mean_gain(('phong', True), ('phong', False))}; the tilt, GGX lobes: "
              f"{mean_gain(('ggx', True), ('ggx', False))}.", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
