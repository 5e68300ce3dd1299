"""How well the maps stand for a brushed metal's anisotropic GGX lobe (issue 11: the anisotropic
sphere's object PSNR). numpy only, no Blender.

A metal sphere (no Fresnel or albedo: the lobe's shape alone), its tangent circling the Z axis as
the SBRDF group's does, seen from three directions under a bundled HDRI. Truth: for every pixel,
the probe's texels (256 rows, tests/reference.py's brute force) integrated with Principled's anisotropic GGX (alphas r²/aspect along
the tangent, r²·aspect across it, aspect = √(1 − 0.9 a); D and Smith G2 with the projected alpha).
PlateLight: the four maps (Phong lobes), looked up with the look-up tilt either as one round lobe
at the roughness's glossiness (*round*) or as the shader does (*streak*: addon/ibl/anisotropy.py:
five look-ups along the streak at the narrow axis's glossiness). PSNR over the sphere's pixels, peak
= the HDRI's 90th percentile by solid angle (bench_lobes.display_peak, as docs/bench/composite.md).

Run: `.venv/bin/python tests/bench/bench_anisotropy.py` (about 3 minutes on 2 cores); writes
docs/bench/anisotropy.md."""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import reference  # noqa: E402
import support  # noqa: E402,F401
from bench_lobes import HDRIS, VIEW_AZIMUTHS, display_peak, gain_summary, lookups, psnr, sphere_view  # noqa: E402
from platelight.addon.demo import bundled_hdris  # noqa: E402
from platelight.addon.exr_io import read_exr  # noqa: E402
from platelight.addon.ibl import anisotropy, maps  # noqa: E402
from platelight.addon.material.principled import roughness_to_glossiness  # noqa: E402

MATERIALS = ((0.2, 0.5), (0.3, 0.3), (0.3, 0.8), (0.45, 1.0), (0.5, 0.5))   # (roughness, anisotropy)
TRUTH_HEIGHT = 256
PIXELS = 28


def along_streak(found, normals, tangents, view, glossiness, amount):
    """The shader's anisotropic look-ups (node_groups/sbrdf.py, probe_maps.py), no Fresnel."""
    narrow = anisotropy.narrow_glossiness(glossiness, amount)
    spread = anisotropy.spread(normals, tangents, view, anisotropy.streak_slope(glossiness, amount))
    centre = lookups(normals, view, narrow, True)
    taps = anisotropy.tap_directions(centre, spread)
    return sum(maps.blended_lookup(found, narrow, d) for d in taps) / len(taps)


def mean_psnrs(env, roughness, amount, views, *shadings):
    """Each shading's PSNR (a function (normals, tangents, view) -> image), averaged over
    ``views``, against brute-force Principled GGX of ``env`` at this roughness and anisotropy,
    the tangent circling Z."""
    aspect = float(anisotropy.aspect(amount))
    scores = [[] for _ in shadings]
    peak = display_peak(env)
    for normals, view in views:
        tangents = reference.tangents_about_z(normals)
        want = reference.anisotropic_ggx(env, roughness ** 2 / aspect, roughness ** 2 * aspect,
                                         normals, tangents, view, TRUTH_HEIGHT)
        for score, shade in zip(scores, shadings):
            score.append(psnr(shade(normals, tangents, view), want, peak))
    return [float(np.mean(score)) for score in scores]


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    views = [sphere_view(a, pixels=PIXELS) for a in VIEW_AZIMUTHS]
    rows = []
    for name in HDRIS:
        env = np.maximum(read_exr(bundled_hdris()[name]), 0).astype(np.float32)
        found = maps.compute_maps(env, maps.MapSettings()).maps
        for roughness, amount in MATERIALS:
            t0 = time.perf_counter()
            glossiness = roughness_to_glossiness(roughness)
            round_db, streak_db = mean_psnrs(
                env, roughness, amount, views,
                lambda n, t, v: maps.blended_lookup(found, glossiness, lookups(n, v, glossiness, True)),
                lambda n, t, v: along_streak(found, n, t, v, glossiness, amount))
            rows.append((name, roughness, amount, round_db, streak_db))
            print(f"{name:10s} r {roughness:.2f} a {amount:.1f}  round {rows[-1][3]:6.2f} dB  "
                  f"streak {rows[-1][4]:6.2f} dB  ({time.perf_counter() - t0:.0f} s)", flush=True)
    write_report(out_dir / "anisotropy.md", rows)


def write_report(path, rows):
    lines = [
        "# Anisotropic lobes: the maps against brushed GGX (issue 11)", "",
        (__doc__.split("\n\n")[1].replace("\n", " ")), "",
        "Produced by `tests/bench/bench_anisotropy.py`.", "",
        "| HDRI | roughness | anisotropy | round lobe (dB) | along the streak (default) | gain |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, roughness, amount, round_db, streak_db in rows:
        lines.append(f"| {name} | {roughness:.2f} | {amount:.1f} | {round_db:.2f} | {streak_db:.2f} | "
                     f"{streak_db - round_db:+.2f} |")
    lines += ["", f"Mean gain over all rows: {gain_summary([r[4] - r[3] for r in rows])}.", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
