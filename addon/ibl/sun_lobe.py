"""The sun's highlight, shaded exactly: a probe's sun taken out of the glossy maps and added back as
one light through the lobe's own GGX (bpy-free).

Blurred maps hold round Phong lobes, read at one glossiness between four fixed widths. For the
smooth sky that is close to GGX, but a small, very bright sun makes the lobe's shape the whole
picture: GGX's long tail gathers it from far off, a brushed lobe smears it into a streak, a
grazing view stretches it. So the bake splits the probe (lights.split_sun: the sun's blob filled
with the sky around it, energy kept) and writes, beside the four contract maps (unchanged), the
diffuse, glossy1 and glossy2 maps of the probe *without* its sun (``<map>_sunless.exr``) and the
sun in the bake record. The shader's specular look-ups read the sunless diffuse and glossy maps
and the mirror map (which keeps the sun), and add the sun through the lobe for their share; the
diffuse term reads the sunless diffuse map and adds the sun's Lambert term (lambert):

    S = sum_k w_k map_k(d) + (w_glossy1 + w_glossy2 + w_diffuse) E D(h) G2(V, L) / (4 (N.V)) (1 + b (1 - A) / A)

h the half vector of the sun direction L and the lobe's view V, D and G2 Principled's anisotropic
GGX with Smith's height-correlated masking (alphas r^2 / aspect along the rotated tangent,
r^2 aspect across it; addon/ibl/anisotropy.py; r the roughness of the glossiness and, at
glossiness 0, of the peak's pull, maps.pulled_roughness), E the sun's irradiance (rgb, lights.py's
units), A the lobe's directional albedo and b how much of what single scattering loses the lobe
gives back (given_back): all of it for a dielectric, whose specular weight rho_s' already follows
its directional albedo E(mu) (the conversion fits it so), so the lobe integrates to 1 like a map's;
F (1 - A) / A for a metal, as Cycles' multiscatter GGX gives it, because a metal's rho_s' holds
only the head-on loss. The alphas are widened by the sun's own size, so a narrow lobe shows a disc,
not a point. (A dielectric's rho_s' already follows E(mu), so giving it F (1 - A) / A too would
count masking's loss twice; docs/decisions.md, "The sun through a rough lobe".)

On a bare metal sphere under the bundled city HDRI (brute-force GGX of the whole HDRI as the
truth; tests/bench/bench_sun_lobe.py, docs/bench/sun_lobe.md) this is the largest single gain of
the glossy look-ups; docs/decisions.md, "The sun's highlight, shaded exactly", has the numbers.
The node groups (node_groups/sbrdf.py, probe_maps.py) build the same formula from these constants.
"""
from __future__ import annotations

import os

import numpy as np

from ..exr_io import write_exr
from . import lights
from .equirect import downsample_area
from .ggx import smith_lambda
from .maps import MAP_NAMES, MapSettings, compute_maps, map_filename, tent_weights

VERSION = 2                 # in the probe's hash: a bake before the sunless grid is baked again

# The maps that lose the sun and where they are written; the mirror map keeps it (a mirror shows
# its disc). Every lobe reads them sunless and adds the sun itself (highlight, lambert).
SUNLESS_MAPS = ("diffuse", "glossy1", "glossy2")
SUNLESS_SUFFIX = "_sunless"
RECORD_KEY = "sun"          # in the bake record: {"direction", "rgb", "angle"}

# A(mu, r): the directional albedo of a white GGX lobe (D, height-correlated Smith G2, no Fresnel)
# seen at N.V = mu, tabulated at ALBEDO_MU for each roughness of ALBEDO_ROUGHNESS, from
# directional_albedo(); linear in between, flat beyond.
ALBEDO_MU = (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75, 0.9, 1.0)
ALBEDO_ROUGHNESS = (0.02, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
ALBEDO = (
    (0.9997, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000, 1.0000),
    (0.9110, 0.9752, 0.9936, 0.9972, 0.9984, 0.9992, 0.9995, 0.9997, 0.9998, 0.9999, 1.0000, 1.0000),
    (0.9118, 0.8881, 0.9278, 0.9587, 0.9749, 0.9884, 0.9934, 0.9957, 0.9969, 0.9977, 0.9981, 0.9983),
    (0.9474, 0.9050, 0.8841, 0.8955, 0.9148, 0.9466, 0.9644, 0.9750, 0.9814, 0.9866, 0.9894, 0.9906),
    (0.9648, 0.9331, 0.8932, 0.8686, 0.8572, 0.8603, 0.8758, 0.8933, 0.9089, 0.9272, 0.9400, 0.9462),
    (0.9636, 0.9292, 0.8820, 0.8499, 0.8257, 0.7963, 0.7839, 0.7821, 0.7867, 0.7995, 0.8146, 0.8245),
    (0.9481, 0.8953, 0.8331, 0.7863, 0.7489, 0.6922, 0.6513, 0.6212, 0.5988, 0.5755, 0.5611, 0.5552),
    (0.9233, 0.8478, 0.7602, 0.6945, 0.6416, 0.5601, 0.4989, 0.4507, 0.4115, 0.3645, 0.3275, 0.3069),
)
# A larger probe (a world HDRI) is split at this height: the sunless maps are at most 64 rows, and
# an 8k HDRI in float64 would take 800 MB.
SPLIT_HEIGHT = 512
# The mean specular weight below which a lobe gives back all single scattering loses (a
# dielectric's, whose rho_s' follows its albedo) and above which F of it (a metal's); around the
# conversion's own line between them (principled.METAL_THRESHOLD, 0.2).
METAL_LIKE = (0.1, 0.3)
# Smallest sin(disc radius) the diffuse horizon is softened over (a point sun: none to speak of).
HORIZON_MIN = 1e-6
# Smallest alpha the shader evaluates (D's peak 1 / (pi alpha^2) stays finite in float32).
MIN_ALPHA = 1e-3
# A disc of angular diameter theta moves the half vector over a disc of slope radius ~theta / 4,
# whose spread a GGX lobe matches with alpha^2 + theta^2 / 32.
SIZE_WIDENING = 1.0 / 32.0


def sunless_name(name: str) -> str:
    return name + SUNLESS_SUFFIX


def sunless_filename(name: str, frame: int | None = None) -> str:
    """``glossy1_sunless.exr`` (single frame) or ``glossy1_sunless_0001.exr`` beside ``glossy1.exr``."""
    return map_filename(name, frame).replace(name, sunless_name(name), 1)


def split(env: np.ndarray, sun: lights.SunSettings | None = None):
    """(sun light, the probe without it) or (None, probe): lights.split_sun with the light's rgb
    kept non-negative (the filled blob can be brighter than the sun in one channel at sunset)."""
    light, sunless = lights.split_sun(env, sun)
    if light is not None:
        light.rgb = np.maximum(light.rgb, 0.0)
        if light.strength <= 0:
            return None, np.asarray(env, dtype=np.float64)[..., :3]
    return light, sunless


def bake_source(env: np.ndarray) -> np.ndarray:
    """The probe as the split (and view_lobe's rungs) read it: finite, non-negative, RGB, at most
    SPLIT_HEIGHT rows (energy kept per texel block)."""
    env = np.asarray(env)[..., :3]
    env = np.where(np.isfinite(env), np.maximum(env, 0.0), 0.0)
    return downsample_area(env, SPLIT_HEIGHT) if env.shape[0] > SPLIT_HEIGHT else env


def bake_sunless(folder: str, env: np.ndarray, settings: MapSettings, maps, frame: int | None = None,
                 found=None) -> dict:
    """Beside a bake's maps: the sunless maps of those of SUNLESS_MAPS it has, and the record's
    entry for the sun ({} without a sun, then no sunless file is left behind). ``found``: the
    split of bake_source(env) when the caller made it already."""
    wanted = [name for name in SUNLESS_MAPS if name in maps]
    if not wanted:
        light, sunless = None, None
    else:
        light, sunless = found if found is not None else split(bake_source(env))
    if light is None:
        remove_sunless(folder, frame)
        return {}
    for name, image in compute_maps(sunless.astype(np.float32), settings, which=wanted).maps.items():
        write_exr(os.path.join(folder, sunless_filename(name, frame)), image)
    remove_sunless(folder, frame, keep=wanted)
    return {RECORD_KEY: to_record(light)}


def remove_sunless(folder: str, frame: int | None, keep=()) -> None:
    for name in SUNLESS_MAPS:
        path = os.path.join(folder, sunless_filename(name, frame))
        if name not in keep and os.path.isfile(path):
            os.unlink(path)


def to_record(light: lights.DirectionalLight) -> dict:
    return {"direction": [float(x) for x in light.direction], "rgb": [float(x) for x in light.rgb],
            "angle": float(light.angle)}


def from_record(record: dict):
    """The sun of a bake record, or None when it has none (or an unreadable one)."""
    sun = record.get(RECORD_KEY) if isinstance(record, dict) else None
    try:
        direction = np.asarray(sun["direction"], dtype=np.float64).reshape(3)
        rgb = np.asarray(sun["rgb"], dtype=np.float64).reshape(3)
        angle = float(sun["angle"])
    except (TypeError, KeyError, ValueError):
        return None
    if not (np.all(np.isfinite(direction)) and np.all(np.isfinite(rgb)) and np.isfinite(angle)):
        return None
    norm = np.linalg.norm(direction)
    if norm <= 0 or np.max(rgb) <= 0:
        return None
    return lights.DirectionalLight(direction / norm, np.maximum(rgb, 0.0), max(angle, 0.0), True)


def directional_albedo(roughness: float, mu: float, steps: int = 1200, turns: int = 512) -> float:
    """A(mu, r) by quadrature over half vectors drawn in GGX's own CDF (exact for any alpha):
    the mean of G2 (V.H) / ((N.H)(N.V)) over H ~ D(H)(N.H), with L = reflect(V, H) above N."""
    a2 = max(roughness, 1e-3) ** 4
    mu = max(mu, 1e-4)
    view = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
    xi = (np.arange(steps) + 0.5) / steps
    phi = (np.arange(turns) + 0.5) / turns * 2.0 * np.pi
    cos_h = 1.0 / np.sqrt(1.0 + a2 * xi / (1.0 - xi))
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    half = np.stack([sin_h[:, None] * np.cos(phi), sin_h[:, None] * np.sin(phi),
                     np.broadcast_to(cos_h[:, None], (steps, turns))], -1)
    vh = half @ view
    nl = 2.0 * vh * half[..., 2] - mu
    g2 = 1.0 / (1.0 + smith_lambda(a2, mu) + smith_lambda(a2, nl))
    return float(np.where((nl > 0) & (vh > 0), g2 * vh / (half[..., 2] * mu), 0.0).mean())


def albedo(roughness, mu) -> np.ndarray:
    """A(mu, r) from the table, as the node group interpolates it (rows blended linearly in r)."""
    roughness, mu = np.asarray(roughness, dtype=np.float64), np.asarray(mu, dtype=np.float64)
    total = np.zeros(np.broadcast(roughness, mu).shape)
    for weight, row in zip(roughness_weights(roughness), ALBEDO):
        total = total + weight * np.interp(mu, ALBEDO_MU, row)
    return total


def roughness_weights(roughness) -> list:
    """Tent weights of the table's rows for ``roughness`` (clamped to the rows' range)."""
    r = np.clip(np.asarray(roughness, dtype=np.float64), ALBEDO_ROUGHNESS[0], ALBEDO_ROUGHNESS[-1])
    knots = ALBEDO_ROUGHNESS
    weights = []
    for k, knot in enumerate(knots):
        below = (r - knots[k - 1]) / (knot - knots[k - 1]) if k > 0 else np.ones_like(r)
        above = (knots[k + 1] - r) / (knots[k + 1] - knot) if k + 1 < len(knots) else np.ones_like(r)
        weights.append(np.clip(np.minimum(below, above), 0.0, 1.0))
    return weights


def albedo_roughness(alpha_t, alpha_b):
    """The roughness whose round lobe's albedo stands for an anisotropic one's: that of the RMS
    alpha (against brute force over random views: 1.2-2.7 % mean error for aspect 0.25-0.33,
    where the geometric mean was 1.9-5.8 %)."""
    return (0.5 * (np.asarray(alpha_t) ** 2 + np.asarray(alpha_b) ** 2)) ** 0.25


def sun_share(glossiness) -> np.ndarray:
    """The part of the lobe the analytic sun stands for: the sunless maps' weights."""
    weights = tent_weights(glossiness)
    return sum(weights[MAP_NAMES.index(name)] for name in SUNLESS_MAPS)


def widened_alpha(alpha, angle):
    return np.sqrt(np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
                   + SIZE_WIDENING * float(angle) ** 2)


def given_back(reflectance) -> np.ndarray:
    """b in the highlight's 1 + b (1 - A) / A, per channel, for a lobe of specular weight F
    (``reflectance``, rgb or a number): 1 where the mean F is a dielectric's (below
    METAL_LIKE[0]), F where it is a metal's (above METAL_LIKE[1]), linear between."""
    reflectance = np.asarray(reflectance, dtype=np.float64)
    mean = np.mean(np.atleast_1d(reflectance), axis=-1, keepdims=reflectance.ndim > 0)
    metal = np.clip((mean - METAL_LIKE[0]) / (METAL_LIKE[1] - METAL_LIKE[0]), 0.0, 1.0)
    return 1.0 - metal * (1.0 - reflectance)


def lambert(normal, light: lights.DirectionalLight) -> np.ndarray:
    """The sun's diffuse light for albedo 1, E max(N.L, 0) / pi, its horizon softened over the
    disc: within sin(r) of it (r the disc's angular radius) N.L is replaced by
    sin(r) q^2, q = clamp((N.L + sin r) / (2 sin r), 0, 1), which meets N.L and 0 there in value
    and slope. The diffuse map cannot carry the sun: bilinear between its texels, 11 degrees
    apart, it reads the terminator's kink up to 3 % of the sun's peak too bright, many times the
    light there (tests/test_sun_lobe.py)."""
    x = np.sum(np.asarray(normal, dtype=np.float64) * light.direction, axis=-1, keepdims=True)
    s = max(float(np.sin(light.angle / 2)), HORIZON_MIN)
    q = np.clip((x + s) / (2 * s), 0.0, 1.0)
    return np.maximum(s * q * q, x) * light.rgb / np.pi


def highlight(normal, tangent, view, alpha_t, alpha_b, light: lights.DirectionalLight,
              reflectance=1.0) -> np.ndarray:
    """E D(h) G2 / (4 (N.V)) (1 + b (1 - A) / A) per point (arrays (..., 3); alphas per point or
    scalars; b = given_back(``reflectance``), the specular weight the term is multiplied by, rgb
    or a number): the sun through the lobe, as the probe group computes it. Zero where the sun or
    the view is below the surface."""
    normal, tangent, view = (np.asarray(x, dtype=np.float64) for x in (normal, tangent, view))
    bitangent = np.cross(normal, tangent)
    a_t = widened_alpha(alpha_t, light.angle)
    a_b = widened_alpha(alpha_b, light.angle)
    sun = np.broadcast_to(light.direction, normal.shape)
    half = sun + view
    half = half / np.maximum(np.linalg.norm(half, axis=-1, keepdims=True), 1e-12)

    def dot(a, b):
        return np.sum(a * b, axis=-1)
    # (h = 0 only where V = -L, the sun or the view below the surface: masked below)
    d = 1.0 / (np.pi * a_t * a_b * np.maximum((dot(half, tangent) / a_t) ** 2 + (dot(half, bitangent) / a_b) ** 2
                                              + dot(half, normal) ** 2, 1e-12) ** 2)

    def smith(w):
        projected = (dot(w, tangent) * a_t) ** 2 + (dot(w, bitangent) * a_b) ** 2
        return (np.sqrt(1.0 + projected / np.maximum(dot(w, normal) ** 2, 1e-12)) - 1.0) / 2.0
    mu_v, mu_l = dot(view, normal), dot(sun, normal)
    roughness = albedo_roughness(alpha_t, alpha_b)
    value = d / (1.0 + smith(view) + smith(sun)) / (4.0 * np.maximum(mu_v, 1e-4))
    value = np.where((mu_v > 0) & (mu_l > 0), value, 0.0)
    lost = 1.0 / albedo(roughness, np.clip(mu_v, 0.0, 1.0)) - 1.0
    return value[..., None] * light.rgb * (1.0 + given_back(reflectance) * lost[..., None])
