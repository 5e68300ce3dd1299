"""View-dependent glossy look-ups: the lobe a glossy surface reflects narrows across the plane of
incidence as the view leaves the normal, and the maps are read that way (bpy-free).

Seen from an angle (N.V = mu < 1), an isotropic GGX lobe reflects into a lobe of directions that
keeps its width in the plane of incidence and narrows across it: tilting the normal by a slope x
moves the mirror direction by 2x in the plane and by 2x mu across it (addon/ibl/anisotropy.py's
rule with the view as the aspect). Brute-force moments put the narrowing at sqrt(mu) in roughness
down to mu of about MU_FLOOR, where it stops. The four round maps are exact only head-on; the
grazing view's narrow lobe is read from them too wide.

So, with Glossy Lobes "View-Dependent GGX" (the default):
- The bake writes a *ladder* of GGX-prefiltered glossy maps beside the contract's four (which keep
  the paper's Phong lobes): glossy1 and glossy2 at the knots' roughness (maps.MAP_ROUGHNESS) and
  one more, glossy3, at GLOSSY3_ROUGHNESS, between glossy2 and the mirror map. Narrowing a
  roughness of 0.3 reads below glossy2 (0.27); there the four maps blend a blurred and a sharp
  image, a poor narrower lobe (34.9 -> 28.8 dB on the copper's head-on band), so the ladder gains a
  rung. The rungs are made from the probe without its sun where the bake splits one
  (addon/ibl/sun_lobe.py): the sun comes through the exact lobe.
- The shader blends the ladder (diffuse, glossy1..3, specular) linearly in roughness, at the
  narrowed roughness r sqrt(max(mu, MU_FLOOR)), in the anisotropic look-ups' taps
  (anisotropy.TAP_SLOPES) spread along the plane of incidence by the slope the narrow lobe lacks,
  alpha sqrt(1 - mu'^2), times TAP_SCALE.

On a bare metal sphere under the bundled HDRIs (tests/bench/bench_view_lobe.py,
docs/bench/view_lobe.md) this gains on every case over the four-map look-up; docs/decisions.md,
"View-dependent glossy look-ups", has the numbers. node_groups/probe_maps.py builds the same rule
from these constants.
"""
from __future__ import annotations

import os

import numpy as np

from ..exr_io import write_exr
from . import sh
from .anisotropy import TAP_SLOPES
from .equirect import dir_to_uv, sample_bilinear
from .maps import DEFAULT_HEIGHTS, GGX_LOBE_CUTOFF, MAP_ROUGHNESS, last_degree_above

VERSION = 1                  # in the probe's hash: a bake before the ladder is baked again
# The scene's Glossy Lobes value that turns the ladder on (the others: maps.LOBES, the four maps).
MODE = "view"
GLOSSY3 = "glossy3"
GLOSSY3_ROUGHNESS = 0.18
RUNGS = ("glossy1", "glossy2", GLOSSY3)          # the ladder's own files, GGX-prefiltered
RUNG_ROUGHNESS = {"glossy1": MAP_ROUGHNESS["glossy1"], "glossy2": MAP_ROUGHNESS["glossy2"],
                  GLOSSY3: GLOSSY3_ROUGHNESS}
RUNG_HEIGHTS = {"glossy1": DEFAULT_HEIGHTS["glossy1"], "glossy2": DEFAULT_HEIGHTS["glossy2"], GLOSSY3: 128}
# The ladder the shader blends, rough to sharp: the contract's diffuse and mirror maps around the rungs.
LADDER = ("diffuse", "glossy1", "glossy2", GLOSSY3, "specular")
LADDER_ROUGHNESS = tuple(MAP_ROUGHNESS.get(name, RUNG_ROUGHNESS.get(name)) for name in LADDER)
# Where the reflected lobe stops narrowing (brute-force moments: r'/r 0.67-0.82 at mu 0.2).
MU_FLOOR = 0.45
# The taps' slopes in units of the missing slope width: two taps at +-0.6 won a sweep on the
# bare-sphere bench; TAP_SLOPES' five taps with the same second moment gain a little more.
TAP_SCALE = 0.6 / float(np.sqrt(np.mean(np.square(TAP_SLOPES))))
PREFIX = "ladder_"
RECORD_KEY = "ladder"        # in the bake record: {"version", "sunless"}


def rung_filename(name: str, frame: int | None = None) -> str:
    """``ladder_glossy3.exr`` (single frame) or ``ladder_glossy3_0001.exr``."""
    if name not in RUNGS:
        raise ValueError(f"unknown ladder rung {name!r}")
    return PREFIX + (f"{name}.exr" if frame is None else f"{name}_{int(frame):04d}.exr")


def ladder_filenames(frame: int | None) -> list[str]:
    return [rung_filename(name, frame) for name in RUNGS]


def in_use(glossy_lobes: str, sampling: str) -> bool:
    """Does a scene read the ladder? With Glossy Lobes "View-Dependent GGX" and exact sampling
    (the paper's sampling reproduces the paper: its four maps)."""
    return glossy_lobes == MODE and sampling == "exact"


def contract_lobes(glossy_lobes: str) -> str:
    """The lobes the contract's four maps are blurred with (MapSettings.lobes): the paper's Phong
    lobes beside the ladder, which holds the GGX ones."""
    return "phong" if glossy_lobes == MODE else glossy_lobes


def wanted(maps) -> bool:
    """Does a probe with these maps need the ladder? Where its lobes read glossy2: every lobe
    that does may narrow down to the mirror map (needs.glossy_maps already asks for every map
    sharper than its glossiness), and the narrowing lives between those two."""
    return "glossy2" in maps


def compute_rungs(env: np.ndarray, heights: dict | None = None) -> dict:
    """The rungs of a probe (float32 (h, 2h, 3) each, clamped at 0): one exact SH analysis at
    the degree the sharpest rung needs (at most the probe's), synthesised with each GGX lobe."""
    heights = {**RUNG_HEIGHTS, **(heights or {})}
    env = np.asarray(env, dtype=np.float32)[..., :3]
    limit = max(2, env.shape[0] - 1)
    factors = {name: sh.ggx_lobe_factors(RUNG_ROUGHNESS[name] ** 2, min(limit, 255)) for name in RUNGS}
    degrees = {name: last_degree_above(f, GGX_LOBE_CUTOFF) for name, f in factors.items()}
    coeffs = sh.project_exact(env, max(degrees.values()))
    rungs = {}
    for name in RUNGS:
        lmax = degrees[name]
        image = sh.synthesize(coeffs[: (lmax + 1) ** 2], int(heights[name]), factors[name][: lmax + 1])
        rungs[name] = np.ascontiguousarray(np.maximum(image, 0.0), dtype=np.float32)
    return rungs


def bake(folder: str, env: np.ndarray, heights: dict, frame: int | None, sunless: bool) -> dict:
    """Write the rungs of ``env`` (the probe without its sun when ``sunless``) and return the
    record's entry."""
    for name, image in compute_rungs(env, heights).items():
        write_exr(os.path.join(folder, rung_filename(name, frame)), image)
    return {RECORD_KEY: {"version": VERSION, "sunless": bool(sunless)}}


def remove(folder: str, frame: int | None) -> None:
    for filename in ladder_filenames(frame):
        path = os.path.join(folder, filename)
        if os.path.isfile(path):
            os.unlink(path)


def record_sunless(record: dict):
    """Whether a record's ladder was made without the sun (True/False), None without a ladder."""
    entry = record.get(RECORD_KEY) if isinstance(record, dict) else None
    if not isinstance(entry, dict) or entry.get("version") != VERSION:
        return None
    return bool(entry.get("sunless"))


# ---- the look-up (numpy; the probe group builds the same)

def narrowed_roughness(roughness, mu, weight=1.0):
    """The roughness the ladder is read at: r sqrt(max(mu, MU_FLOOR)) (mu clamped to [0, 1]), the
    narrowing scaled by ``weight`` (view_weight)."""
    factor = np.sqrt(np.maximum(np.clip(mu, 0.0, 1.0), MU_FLOOR))
    return np.asarray(roughness) * (1.0 + np.asarray(weight) * (factor - 1.0))


def view_weight(alpha_t, alpha_b):
    """How much of the view's narrowing and spread an anisotropic lobe gets: (alpha_b / alpha_t)^2,
    1 for a round lobe. A brushed lobe's own streak already spreads its look-ups, and on the
    bare-sphere bench the view's rule on top of it cost 0.3-1.1 dB."""
    return (np.asarray(alpha_b) / np.maximum(np.asarray(alpha_t), 1e-12)) ** 2


def ladder_weights(roughness, with_glossy3: bool = True) -> np.ndarray:
    """Tent weights of LADDER's maps (axis 0), linear in roughness. Without glossy3 its weight
    goes to glossy2 and the mirror map in the proportion that makes this the four maps' rule
    exactly (maps.tent_weights: linear in roughness between the same knots)."""
    r = np.asarray(roughness, dtype=np.float64)
    knots = np.asarray(LADDER_ROUGHNESS)
    position = np.interp(-r, -knots, np.arange(len(knots)))
    weights = np.stack([np.maximum(0.0, 1.0 - np.abs(position - k)) for k in range(len(knots))])
    if not with_glossy3:
        third = LADDER.index(GLOSSY3)
        share = fold_share()
        weights[third - 1] += weights[third] * share
        weights[third + 1] += weights[third] * (1.0 - share)
        weights[third] = 0.0
    return weights


def fold_share() -> float:
    """The part of glossy3's weight glossy2 takes when there is no glossy3."""
    g2, g3, mirror = (LADDER_ROUGHNESS[LADDER.index(n)] for n in ("glossy2", GLOSSY3, "specular"))
    return (g3 - mirror) / (g2 - mirror)


def sun_share(weights):
    """The part of the lobe the analytic sun stands for (sun_lobe.sun_share on the ladder): the
    rungs' and the diffuse map's weights (every map but the mirror's is read sunless)."""
    return sum(weights[LADDER.index(name)] for name in RUNGS) + weights[0]


def spread(normal, view, alpha, mu_floor=MU_FLOOR):
    """The taps' spread vector along the plane of incidence, per point: anisotropy.spread with the
    in-plane tangent T = (V - mu N) / |V - mu N| and the missing slope alpha sqrt(1 - mu'^2),
    which is 2 alpha sqrt(1 - mu'^2) (sqrt(1 - mu^2) N + mu T)."""
    normal, view = np.asarray(normal, dtype=np.float64), np.asarray(view, dtype=np.float64)
    mu = np.clip(np.sum(normal * view, axis=-1, keepdims=True), 0.0, 1.0)
    in_plane = view - mu * normal
    in_plane = in_plane / np.maximum(np.linalg.norm(in_plane, axis=-1, keepdims=True), 1e-12)
    missing = np.asarray(alpha)[..., None] * np.sqrt(1.0 - np.maximum(mu, mu_floor) ** 2)
    return 2.0 * missing * (np.sqrt(1.0 - mu * mu) * normal + mu * in_plane)


def lookup(ladder_images: dict, direction, normal, view, roughness, with_glossy3=True, streak=None, weight=1.0):
    """The ladder read at the narrowed roughness in the taps around ``direction`` (unit, (..., 3)):
    the probe group's glossy look-up, without the sun, Fresnel or parallax. ``ladder_images``:
    LADDER name -> map (the rungs sunless where the probe has a sun); ``roughness`` that of the
    lobe's narrow axis; ``streak`` an anisotropic lobe's own spread (anisotropy.spread), which the
    taps follow with the view's; ``weight``: view_weight of the lobe."""
    mu = np.clip(np.sum(np.asarray(normal) * np.asarray(view), axis=-1), 0.0, 1.0)
    roughness = np.broadcast_to(np.asarray(roughness, dtype=np.float64), mu.shape)
    weights = ladder_weights(narrowed_roughness(roughness, mu, weight), with_glossy3)
    offset = spread(normal, view, roughness ** 2) * (TAP_SCALE * np.asarray(weight))[..., None]
    if streak is not None:
        offset = offset + streak
    total = 0.0
    for slope in TAP_SLOPES:
        tap = direction + slope * offset
        u, v = dir_to_uv(tap / np.linalg.norm(tap, axis=-1, keepdims=True))
        total = total + sum(w[..., None] * sample_bilinear(ladder_images[name], u, v)
                            for name, w in zip(LADDER, weights) if np.any(w > 0))
    return total / len(TAP_SLOPES)

