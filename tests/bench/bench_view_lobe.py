"""View-dependent glossy look-ups (addon/ibl/view_lobe.py, Glossy Lobes "View-Dependent GGX", the
default) against the four round maps (Glossy Lobes "Phong", the paper's; issue 11: the glossy sphere's
object PSNR stopped at about 35 dB; docs/decisions.md, "View-dependent glossy look-ups"). numpy only,
no Blender: the same functions the probe group's nodes are tested against.

Seen from an angle (N.V = mu < 1), an isotropic GGX lobe reflects into a lobe of directions that
keeps its width in the plane of incidence but narrows across it. view_lobe reads a ladder of
GGX-prefiltered maps (glossy1, glossy2 and a fifth map, glossy3, at roughness 0.18, between the
contract's diffuse and mirror maps) at the narrowed roughness r sqrt(max(mu, 0.45)), in five taps
spread along the plane of incidence by the slope the narrow lobe lacks. The middle column reads the
same ladder as if head-on (the ladder alone, no view dependence).

A metal sphere (no Fresnel: the lobe's shape alone), seen from three directions under each bundled
HDRI, as bench_sun_lobe.py: truth brute-force Principled GGX of the HDRI (256 rows); every route
reads sunless maps and adds the sun through the lobe (addon/ibl/sun_lobe.py) for the share the
sunless maps carry. PSNR over the sphere's pixels, peak = the HDRI's 90th percentile by solid angle
(bench_lobes.display_peak).

Run: `.venv/bin/python tests/bench/bench_view_lobe.py` (about 5 minutes on 2 cores); writes
docs/bench/view_lobe.md."""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import support  # noqa: E402,F401
from bench_anisotropy import MATERIALS as BRUSHED, mean_psnrs  # noqa: E402
from bench_lobes import HDRIS, VIEW_AZIMUTHS, gain_summary, lookups, sphere_view  # noqa: E402
from bench_sun_lobe import hdri_maps, shaded  # noqa: E402
from platelight.addon.ibl import anisotropy, maps, sun_lobe, view_lobe  # noqa: E402

ROUGHNESS = (0.1, 0.2, 0.3, 0.45, 0.6)
PIXELS = 28


def ladder_maps(env, sun, sunless_env, sunless):
    """LADDER name -> map as the bake makes them (rungs from the probe without its sun, around
    them the diffuse map the specular look-ups read, sunless where the sun is split, and the mirror
    map, both from hdri_maps' ``sunless``), and the seconds the rungs took."""
    t0 = time.perf_counter()
    rungs = view_lobe.compute_rungs(sunless_env if sun is not None else env)
    seconds = time.perf_counter() - t0
    return {**rungs, "diffuse": sunless["diffuse"], "specular": sunless["specular"]}, seconds


def ladder_shaded(ladder, normals, tangents, view, roughness, sun, view_dependent):
    """The product's look-up (view_lobe.lookup), or the ladder alone (read as if head-on), plus
    the sun through the exact lobe for the share the sunless maps carry."""
    alpha = roughness ** 2
    centre = lookups(normals, view, maps.roughness_to_glossiness(roughness), True)
    view = np.broadcast_to(view, normals.shape)
    seen_from = view if view_dependent else normals
    image = view_lobe.lookup(ladder, centre, normals, seen_from, roughness)
    if sun is None:
        return image
    mu = np.clip(np.sum(normals * seen_from, axis=-1), 0.0, 1.0)
    share = view_lobe.sun_share(view_lobe.ladder_weights(view_lobe.narrowed_roughness(roughness, mu)))
    return image + share[:, None] * sun_lobe.highlight(normals, tangents, view, alpha, alpha, sun)


def brushed_shaded(ladder, normals, tangents, view, roughness, amount, sun, weight):
    """An anisotropic lobe as the shader reads it: the ladder at the narrow axis's roughness, the
    taps along its streak plus the view's spread, both scaled by ``weight`` (1: in full; the
    product's view_lobe.view_weight; 0: the ladder alone), plus the sun through the exact lobe."""
    glossiness = maps.roughness_to_glossiness(roughness)
    narrow = anisotropy.narrow_glossiness(glossiness, amount)
    narrow_roughness = maps.glossiness_to_roughness(narrow)
    streak = anisotropy.spread(normals, tangents, view, anisotropy.streak_slope(glossiness, amount))
    centre = lookups(normals, view, narrow, True)
    view = np.broadcast_to(view, normals.shape)
    image = view_lobe.lookup(ladder, centre, normals, view, narrow_roughness, streak=streak, weight=weight)
    if sun is None:
        return image
    mu = np.clip(np.sum(normals * view, axis=-1), 0.0, 1.0)
    share = view_lobe.sun_share(view_lobe.ladder_weights(view_lobe.narrowed_roughness(narrow_roughness, mu, weight)))
    aspect = float(anisotropy.aspect(amount))
    return image + share[:, None] * sun_lobe.highlight(normals, tangents, view, roughness ** 2 / aspect,
                                                       roughness ** 2 * aspect, sun)


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    views = [sphere_view(a, pixels=PIXELS) for a in VIEW_AZIMUTHS]
    rows, brushed = [], []
    for name in HDRIS:
        env, _, sun, sunless_env, sunless = hdri_maps(name)
        ladder, seconds = ladder_maps(env, sun, sunless_env, sunless)
        for roughness in ROUGHNESS:
            t0 = time.perf_counter()
            scores = mean_psnrs(
                env, roughness, 0.0, views,
                lambda n, t, v: shaded(sunless, n, t, v, roughness, 0.0, sun),
                lambda n, t, v: ladder_shaded(ladder, n, t, v, roughness, sun, False),
                lambda n, t, v: ladder_shaded(ladder, n, t, v, roughness, sun, True))
            rows.append((name, roughness, *scores, seconds))
            print(f"{name:10s} r {roughness:.2f}  phong {scores[0]:6.2f}  ladder {scores[1]:6.2f}  "
                  f"ladder+view {scores[2]:6.2f} dB  ({time.perf_counter() - t0:.0f} s)", flush=True)
        for roughness, amount in BRUSHED:
            aspect = float(anisotropy.aspect(amount))
            weight = float(view_lobe.view_weight(1.0 / aspect, aspect))
            scores = mean_psnrs(
                env, roughness, amount, views,
                lambda n, t, v: shaded(sunless, n, t, v, roughness, amount, sun),
                *(lambda n, t, v, w=w: brushed_shaded(ladder, n, t, v, roughness, amount, sun, w)
                  for w in (0.0, 1.0, weight)))
            brushed.append((name, roughness, amount, *scores))
            print(f"{name:10s} r {roughness:.2f} a {amount:.1f}  " + "  ".join(f"{s:6.2f}" for s in scores), flush=True)
    write_report(out_dir / "view_lobe.md", rows, brushed)


def write_report(path, rows, brushed):
    lines = [
        "# View-dependent glossy look-ups (issue 11)", "",
        " ".join(__doc__.split("\n\n")[1].split()), "", " ".join(__doc__.split("\n\n")[2].split()), "",
        "Produced by `tests/bench/bench_view_lobe.py`.", "",
        "Cost: the four maps read two maps per shading point (the glossiness's neighbours), the view-dependent "
        "look-up ten (two in each of five taps); the bake adds the three rungs, whose numpy time (one SH analysis "
        "of the HDRI at the degree glossy3 needs, synthesis at 32, 64 and 128 rows, after the four maps' analysis "
        "has cached the quadrature tables, as in a bake) is the last column.", "",
        "| HDRI | roughness | four Phong maps (dB) | GGX ladder, head-on | view-dependent (default) | gain | rungs (s) |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, roughness, default, ladder, view, seconds in rows:
        lines.append(f"| {name} | {roughness:.2f} | {default:.2f} | {ladder:.2f} | {view:.2f} | {view - default:+.2f} "
                     f"| {seconds:.2f} |")
    lines += ["", "Mean gain of the view-dependent look-ups over the four Phong maps: "
              f"{gain_summary([r[4] - r[2] for r in rows])}.", "",
              "## Anisotropic lobes", "",
              "A brushed lobe's taps already follow its streak (addon/ibl/anisotropy.py); the view's narrowing and "
              "spread come on top, scaled by a weight: none (the ladder alone), in full, or the default "
              "view_lobe.view_weight, (alpha_b / alpha_t)^2. The materials of bench_anisotropy.py.", "",
              "| HDRI | roughness | anisotropy | four Phong maps (dB) | ladder alone | view in full | view weighted (default) | gain |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, roughness, amount, phong, alone, full, weighted in brushed:
        lines.append(f"| {name} | {roughness:.2f} | {amount:.1f} | {phong:.2f} | {alone:.2f} | {full:.2f} | "
                     f"{weighted:.2f} | {weighted - phong:+.2f} |")
    lines += ["", "Mean gain of the default over the four Phong maps on brushed lobes: "
              f"{gain_summary([r[6] - r[3] for r in brushed])}.", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
