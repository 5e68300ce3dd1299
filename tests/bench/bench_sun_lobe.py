"""How much the exactly shaded sun (addon/ibl/sun_lobe.py) brings the glossy look-ups towards GGX
(issue 11: the glossy and brushed spheres' object PSNR). numpy only, no Blender.

A metal sphere (no Fresnel or albedo: the lobe's shape alone), its tangent circling the Z axis as
the SBRDF group's does, seen from three directions under a bundled HDRI. Truth: for every pixel,
the HDRI's texels (256 rows, tests/reference.py's brute force) integrated with Principled's
(anisotropic) GGX, D and Smith G2, normalised over the hemisphere. PlateLight: the look-ups as the
shader makes them (tilted, along the streak when anisotropic), reading either the four maps with
the sun blurred in (the paper's maps) or the sunless maps plus the
sun through the lobe (the default). HDRIs without a sun (courtyard) read the same maps both
ways. PSNR over the sphere's pixels, peak = the HDRI's 90th percentile by solid angle
(bench_lobes.display_peak, as docs/bench/composite.md).

Run: `.venv/bin/python tests/bench/bench_sun_lobe.py` (about 4 minutes on 2 cores); writes
docs/bench/sun_lobe.md."""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import support  # noqa: E402,F401
from bench_anisotropy import along_streak, mean_psnrs  # noqa: E402
from bench_lobes import HDRIS, VIEW_AZIMUTHS, gain_summary, lookups, sphere_view  # noqa: E402
from platelight.addon.demo import bundled_hdris  # noqa: E402
from platelight.addon.exr_io import read_exr  # noqa: E402
from platelight.addon.ibl import anisotropy, maps, sun_lobe  # noqa: E402

MATERIALS = ((0.1, 0.0), (0.2, 0.0), (0.3, 0.0), (0.45, 0.0), (0.6, 0.0), (0.8, 0.0),
             (0.3, 0.8), (0.45, 1.0))               # (roughness, anisotropy)
PIXELS = 28


def shaded(found, normals, tangents, view, roughness, amount, sun=None):
    """The shader's specular lobe (no Fresnel): the maps' look-ups, plus the sun through the lobe
    when ``sun`` is given (then ``found`` holds the sunless maps)."""
    glossiness = maps.roughness_to_glossiness(roughness)
    if amount:
        image = along_streak(found, normals, tangents, view, glossiness, amount)
        narrow = anisotropy.narrow_glossiness(glossiness, amount)
    else:
        image = maps.blended_lookup(found, glossiness, lookups(normals, view, glossiness, True))
        narrow = glossiness
    if sun is None:
        return image
    aspect = float(anisotropy.aspect(amount))
    return image + sun_lobe.sun_share(narrow) * sun_lobe.highlight(
        normals, tangents, np.broadcast_to(view, normals.shape), roughness ** 2 / aspect,
        roughness ** 2 * aspect, sun)


def hdri_maps(name):
    """A bundled HDRI and what the bake makes of it: (env, the four maps, its sun or None, the env
    without its sun, the maps the shader reads with the sun lobe: sunless where the bake splits)."""
    env = np.maximum(read_exr(bundled_hdris()[name]), 0).astype(np.float32)
    full = maps.compute_maps(env, maps.MapSettings()).maps
    sun, sunless_env = sun_lobe.split(env)
    sunless = dict(full)
    if sun is not None:
        sunless.update(maps.compute_maps(sunless_env.astype(np.float32), maps.MapSettings(),
                                         which=sun_lobe.SUNLESS_MAPS).maps)
    return env, full, sun, sunless_env, sunless


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    views = [sphere_view(a, pixels=PIXELS) for a in VIEW_AZIMUTHS]
    rows = []
    for name in HDRIS:
        env, full, sun, _, sunless = hdri_maps(name)
        for roughness, amount in MATERIALS:
            t0 = time.perf_counter()
            before, after = mean_psnrs(env, roughness, amount, views,
                                       lambda n, t, v: shaded(full, n, t, v, roughness, amount),
                                       lambda n, t, v: shaded(sunless, n, t, v, roughness, amount, sun))
            rows.append((name, sun is not None, roughness, amount, before, after))
            print(f"{name:10s} r {roughness:.2f} a {amount:.1f}  maps {rows[-1][4]:6.2f} dB  "
                  f"sun lobe {rows[-1][5]:6.2f} dB  ({time.perf_counter() - t0:.0f} s)", flush=True)
    write_report(out_dir / "sun_lobe.md", rows)


def write_report(path, rows):
    lines = [
        "# The sun shaded exactly: glossy look-ups against GGX (issue 11)", "",
        (__doc__.split("\n\n")[1].replace("\n", " ")), "",
        "Produced by `tests/bench/bench_sun_lobe.py`.", "",
        "| HDRI | sun found | roughness | anisotropy | sun in the maps (dB) | sun through the lobe (default) | gain |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for name, found, roughness, amount, before, after in rows:
        lines.append(f"| {name} | {'yes' if found else 'no'} | {roughness:.2f} | {amount:.1f} | {before:.2f} | "
                     f"{after:.2f} | {after - before:+.2f} |")
    gains = [r[5] - r[4] for r in rows if r[1]]
    if gains:
        lines += ["", f"Mean gain where a sun was found: {gain_summary(gains)}.", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
