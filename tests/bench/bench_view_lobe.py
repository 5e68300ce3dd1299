"""A view-dependent glossy look-up, prototyped in numpy (issue 11: the glossy sphere's object PSNR
stops at about 35 dB; docs/decisions.md, "The head-on band's error is the lobe's view dependence").
Not in the shader yet: this measures the design before it is built. numpy only, no Blender.

Seen from an angle (N.V = mu < 1), an isotropic GGX lobe reflects into a lobe of directions that
keeps its width in the plane of incidence but narrows across it, to about mu times (tilting the
normal by a slope x moves the mirror direction by 2x in the plane and by 2x mu across it;
addon/ibl/anisotropy.py). The maps hold round lobes, exact only head-on. The prototype reads the
maps at the narrow axis's roughness, r sqrt(max(mu, MU_FLOOR)) (alpha times mu), in two look-ups
spread along the plane of incidence by the slope the narrow lobe lacks, alpha sqrt(1 - mu^2), at
slopes +-TAP_SLOPE (the anisotropic look-ups' rule with the view's aspect). Narrowing a roughness of
0.3 needs a map sharper than glossy2 (GGX roughness 0.27): between glossy2 and the mirror map the
maps blend a blurred and a sharp image, a poor narrower lobe, so the prototype adds one map to the
ladder, glossy3, GGX-prefiltered at LADDER_ROUGHNESS (glossy1 and glossy2 GGX-prefiltered too), and
blends the ladder linearly in roughness.

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
from bench_anisotropy import mean_psnrs  # noqa: E402
from bench_lobes import HDRIS, VIEW_AZIMUTHS, gain_summary, lookups, sphere_view  # noqa: E402
from bench_sun_lobe import hdri_maps, shaded  # noqa: E402
from platelight.addon.ibl import anisotropy, maps, sh, sun_lobe  # noqa: E402
from platelight.addon.ibl.equirect import dir_to_uv, sample_bilinear  # noqa: E402

ROUGHNESS = (0.1, 0.2, 0.3, 0.45, 0.6)
PIXELS = 28
LADDER_ROUGHNESS = 0.18        # glossy3, between glossy2 (0.27) and the mirror map
LADDER_HEIGHT = 128
MU_FLOOR = 0.45                # below it the lobe stops narrowing (brute-force moments: r'/r 0.67-0.82 at mu 0.2)
TAP_SLOPE = 0.6                # the two look-ups' slope, in units of the missing slope width


def ladder_maps(env, sunless_env):
    """The sunless ladder, rough to sharp: (roughness knots, maps, seconds glossy3 took: its
    SH analysis and synthesis, what the bake would add). glossy1/2 GGX-prefiltered, glossy3 the
    prototype's extra map; the mirror map keeps the sun (as the shader's)."""
    source = sunless_env.astype(np.float32)
    contract = maps.compute_maps(source, maps.MapSettings(lobes="ggx"), which=("diffuse", "glossy1", "glossy2")).maps
    t0 = time.perf_counter()
    alpha = LADDER_ROUGHNESS ** 2
    lmax = min(int(np.argmax(sh.ggx_lobe_factors(alpha, 255) < maps.GGX_LOBE_CUTOFF)), source.shape[0] - 1)
    coeffs = sh.project_exact(source, lmax)
    glossy3 = np.maximum(sh.synthesize(coeffs, LADDER_HEIGHT, sh.ggx_lobe_factors(alpha, lmax)), 0)
    glossy3_seconds = time.perf_counter() - t0
    specular = maps.compute_maps(env.astype(np.float32), maps.MapSettings(), which=("specular",)).maps["specular"]
    knots = (maps.MAP_ROUGHNESS["diffuse"], maps.MAP_ROUGHNESS["glossy1"], maps.MAP_ROUGHNESS["glossy2"],
             LADDER_ROUGHNESS, 0.0)
    return knots, [contract["diffuse"], contract["glossy1"], contract["glossy2"], glossy3, specular], glossy3_seconds


def ladder_weights(knots, roughness):
    """Tent weights over the ladder, linear in roughness, per point (knots descending)."""
    position = np.interp(-np.asarray(roughness, dtype=np.float64), -np.asarray(knots), np.arange(len(knots)))
    return [np.maximum(0.0, 1.0 - np.abs(position - k)) for k in range(len(knots))]


def ladder_lookup(ladder, roughness, directions):
    knots, images, _ = ladder
    u, v = dir_to_uv(directions)
    weights = ladder_weights(knots, np.broadcast_to(roughness, directions.shape[:-1]))
    return sum(w[..., None] * sample_bilinear(image, u, v) for w, image in zip(weights, images) if w.max() > 0)


def ladder_shaded(ladder, normals, tangents, view, roughness, sun, view_dependent):
    """The prototype: the ladder at the roughness (or narrowed by the view, in two look-ups along
    the plane of incidence), plus the sun through the exact lobe for the sunless share."""
    alpha = roughness ** 2
    centre = lookups(normals, view, maps.roughness_to_glossiness(roughness), True)
    view = np.broadcast_to(view, normals.shape)
    mu = np.clip(np.sum(normals * view, axis=-1), 1e-4, 1.0)
    if view_dependent:
        narrow_mu = np.maximum(mu, MU_FLOOR)
        narrow = roughness * np.sqrt(narrow_mu)
        in_plane = view - mu[:, None] * normals
        in_plane /= np.maximum(np.linalg.norm(in_plane, axis=-1, keepdims=True), 1e-9)
        spread = anisotropy.spread(normals, in_plane, view, alpha * np.sqrt(1.0 - narrow_mu ** 2))
        image = sum(ladder_lookup(ladder, narrow, d / np.linalg.norm(d, axis=-1, keepdims=True))
                    for d in (centre + s * TAP_SLOPE * spread for s in (-1.0, 1.0))) / 2.0
    else:
        narrow = np.full(mu.shape, roughness)
        image = ladder_lookup(ladder, narrow, centre)
    if sun is None:
        return image
    share = 1.0 - ladder_weights(ladder[0], narrow)[-1]
    return image + share[:, None] * sun_lobe.highlight(normals, tangents, view, alpha, alpha, sun)


def main(out_dir: pathlib.Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    views = [sphere_view(a, pixels=PIXELS) for a in VIEW_AZIMUTHS]
    rows = []
    for name in HDRIS:
        env, _, sun, sunless_env, sunless = hdri_maps(name)
        ladder = ladder_maps(env, sunless_env if sun is not None else env)
        for roughness in ROUGHNESS:
            t0 = time.perf_counter()
            scores = mean_psnrs(
                env, roughness, 0.0, views,
                lambda n, t, v: shaded(sunless, n, t, v, roughness, 0.0, sun),
                lambda n, t, v: ladder_shaded(ladder, n, t, v, roughness, sun, False),
                lambda n, t, v: ladder_shaded(ladder, n, t, v, roughness, sun, True))
            rows.append((name, roughness, *scores, ladder[2]))
            print(f"{name:10s} r {roughness:.2f}  default {scores[0]:6.2f}  ladder {scores[1]:6.2f}  "
                  f"ladder+view {scores[2]:6.2f} dB  ({time.perf_counter() - t0:.0f} s)", flush=True)
    write_report(out_dir / "view_lobe.md", rows)


def write_report(path, rows):
    lines = [
        "# A view-dependent glossy look-up, prototyped (issue 11)", "",
        " ".join(__doc__.split("\n\n")[1].split()), "", " ".join(__doc__.split("\n\n")[2].split()), "",
        "Produced by `tests/bench/bench_view_lobe.py`.", "",
        "Cost: the default reads two maps per shading point (the glossiness's neighbours), the prototype four "
        "(two in each look-up); the bake adds glossy3, whose numpy time (SH analysis of the HDRI at the degree its "
        "lobe needs, synthesis at 128 rows) is the last column.", "",
        "| HDRI | roughness | default (dB) | + glossy3 ladder | + view-dependent look-ups | gain | glossy3 (s) |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, roughness, default, ladder, view, seconds in rows:
        lines.append(f"| {name} | {roughness:.2f} | {default:.2f} | {ladder:.2f} | {view:.2f} | {view - default:+.2f} "
                     f"| {seconds:.1f} |")
    lines += ["", "Mean gain of the view-dependent look-ups over the default: "
              f"{gain_summary([r[4] - r[2] for r in rows])}.", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
