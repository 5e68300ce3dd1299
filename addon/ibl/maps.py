"""The four blurred maps of a probe (design.md): diffuse, glossy1, glossy2, specular.

Each map holds the outgoing radiance of a white surface under the probe's light, so a constant
environment of 1 gives 1 everywhere (white furnace).

Two modes (``MapSettings.sampling``):
- ``"exact"`` (default): one exact SH analysis of the full-resolution probe (FFT along rows +
  Fejér quadrature, sh.project_exact) at the degree each lobe needs to be converged (lobe factors
  below 1e-7), then synthesis onto each map's grid; specular is an area-correct downsample.
- ``"paper"``: the paper's method — SH by the paper's stratified sampling (Eq 8–9): diffuse from
  degree 2, glossy1 from degree 15; glossy2 by brute-force spatial convolution of the probe
  (downsampled to twice the map's resolution); specular an area-correct downsample.
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from functools import lru_cache

import numpy as np

from ..errors import PlateLightError
from ..exr_io import write_exr
from . import sh
from .equirect import (check_shape, dir_to_uv, downsample_area, sample_bilinear, texel_directions,
                       texel_solid_angles)

MAP_NAMES = ("diffuse", "glossy1", "glossy2", "specular")
# The glossiness rule (design.md), written once: map k is exact at glossiness n = k / 3, and in
# between the two neighbouring maps blend linearly (tent weights). The bake reads it to compute
# only the maps a material samples (bake/needs.py), the shader to blend them (node_groups/probe_maps.py).
GLOSSINESS_SCALE = len(MAP_NAMES) - 1
MAP_GLOSSINESS = {name: k / GLOSSINESS_SCALE for k, name in enumerate(MAP_NAMES)}
DEFAULT_HEIGHTS = {"diffuse": 16, "glossy1": 32, "glossy2": 64, "specular": 128}
# The GGX roughness whose reflection lobe (head-on view) holds half its energy within the same
# angle as each map's lobe (tests/test_material.py finds them by bisection): the Principled
# conversion's knots, and the roughness the "ggx" glossy lobes prefilter with.
MAP_ROUGHNESS = {"diffuse": 0.6436, "glossy1": 0.4429, "glossy2": 0.2702, "specular": 0.0}
# Between the maps, glossiness and roughness are linear: the knots, from rough to sharp.
ROUGHNESS_KNOTS = tuple(MAP_ROUGHNESS[name] for name in MAP_NAMES)
GLOSSINESS_KNOTS = tuple(MAP_GLOSSINESS[name] for name in MAP_NAMES)
# The glossy maps' lobes: the paper's normalised Phong cos^s, or GGX's reflection lobe at the
# map's roughness (what Cycles' Principled BSDF reflects; docs/decisions.md, "Glossy lobes").
LOBES = ("phong", "ggx")
# GGX's factors fall fast to about 1e-5, then only polynomially (the lobe is cut at the horizon):
# beyond that degree the map's own grid cannot hold them anyway.
GGX_LOBE_CUTOFF = 1e-5
MAX_PROBE_HEIGHT = 16384
SH_JSON_LMAX = 15
# A lobe's SH series is cut where its factors fall below this (relative to λ_0 = 1).
LOBE_CUTOFF = 1e-7
# The clamped cosine's factors decay only as l^-2.5; this degree keeps the diffuse map within
# 0.1 % of brute force on sunny probes (docs/bench/maps.md) at no measurable cost.
DIFFUSE_LMAX_EXACT = 48


def lobe_half_angle(exponent: float) -> float:
    """Degrees from R within which the normalized Phong lobe (s+1)/(2 pi) cos^s holds half its
    energy: 1 - cos^(s+1) = 1/2."""
    return math.degrees(math.acos(0.5 ** (1.0 / (exponent + 1.0))))


def footprint_glossiness(glossiness, ratio):
    """The glossiness whose lobe is ``ratio`` times as wide (half-energy angle, piecewise linear
    between the maps' angles) as that of ``glossiness``. The maps are blurred as seen from the
    probe's centre; a reflected ray that meets a surface at distance t from the shading point and
    d from the centre sees a lobe of angle a there as wide as a lobe of a t / d seen from the
    centre (Lagarde and Zanuttini's distance-based roughness, 2012). A wide lobe meets surfaces at
    many distances, so the one its central ray meets stands for its footprint only when it is
    narrow: the ratio applies in full up to glossy1's angle and fades out linearly towards the
    diffuse lobe's (applied in full to the diffuse sphere's rough specular lobe it cost 0.17 dB,
    docs/decisions.md). The node group builds the same rule (node_groups/probe_maps.py)."""
    knots = np.asarray(MAP_HALF_ANGLES)                   # at map positions k = 0..3
    position = np.clip(np.asarray(glossiness, dtype=np.float64), 0.0, 1.0) * GLOSSINESS_SCALE
    angle = np.interp(position, np.arange(len(knots)), knots)
    fade = np.clip((knots[0] - angle) / (knots[0] - knots[1]), 0.0, 1.0)
    ratio = 1.0 - (1.0 - np.clip(np.asarray(ratio, dtype=np.float64), 0.0, 1.0)) * fade
    narrowed = angle * ratio
    return np.interp(narrowed, knots[::-1], np.arange(len(knots))[::-1]) / GLOSSINESS_SCALE


def tent_weights(glossiness) -> np.ndarray:
    """Blend weight of each map (axis 0, in MAP_NAMES order) for ``glossiness`` (a number or an
    array, clamped to [0, 1]): max(0, 1 - |3 n - k|); at most two are non-zero and they sum to 1."""
    position = np.clip(np.asarray(glossiness, dtype=np.float64), 0.0, 1.0) * GLOSSINESS_SCALE
    return np.stack([np.maximum(0.0, 1.0 - np.abs(position - k)) for k in range(len(MAP_NAMES))])


def roughness_to_glossiness(roughness):
    """The glossiness of a GGX roughness (a number or an array), linear between the maps' knots."""
    return np.interp(roughness, ROUGHNESS_KNOTS[::-1], GLOSSINESS_KNOTS[::-1])


def glossiness_to_roughness(glossiness):
    return np.interp(glossiness, GLOSSINESS_KNOTS, ROUGHNESS_KNOTS)


PULL_BELOW = 1e-6           # the glossiness below which a pulled peak widens the lobe


def pulled_roughness(glossiness, cx, cy):
    """The GGX roughness a lobe stands for: its glossiness's, and at glossiness 0 (the diffuse
    map's roughness, the widest a map holds) up to 1 as far as its Lafortune peak is pulled from
    the mirror direction to N, 1 - max(|Cx|, |Cy|) (principled.peak_pull writes it this way)."""
    pull = np.clip(1.0 - np.maximum(np.abs(cx), np.abs(cy)), 0.0, 1.0) * (np.asarray(glossiness) < PULL_BELOW)
    return glossiness_to_roughness(glossiness) + pull * (1.0 - ROUGHNESS_KNOTS[0])


def map_weights(glossiness: float) -> dict[str, float]:
    """tent_weights() of one glossiness, by map name."""
    return {name: float(w) for name, w in zip(MAP_NAMES, tent_weights(float(glossiness)))}


def blended_lookup(maps_by_name: dict, glossiness: float, directions: np.ndarray) -> np.ndarray:
    """The maps blended at ``glossiness`` and read bilinearly along unit ``directions`` (..., 3):
    the probe group's specular look-up in numpy (no Fresnel, albedo or parallax)."""
    u, v = dir_to_uv(directions)
    return sum(w * sample_bilinear(maps_by_name[name], u, v)
               for name, w in map_weights(glossiness).items() if w > 0)


@dataclasses.dataclass
class MapSettings:
    sampling: str = "exact"            # "exact" or "paper"
    samples: int = 4096                # paper mode: number of stratified samples (k² is used)
    seed: int | None = 0               # paper mode: jitter seed (None: random)
    glossy1_exponent: float = 8.0
    glossy2_exponent: float = 64.0
    lobes: str = "phong"               # glossy maps' lobes (LOBES); the paper's sampling is Phong
    heights: dict = dataclasses.field(default_factory=lambda: dict(DEFAULT_HEIGHTS))
    paper_diffuse_lmax: int = 2
    paper_glossy1_lmax: int = 15

    def validate(self) -> None:
        if self.sampling not in ("exact", "paper"):
            raise PlateLightError(f"Unknown sampling mode {self.sampling!r}; use 'exact' or 'paper'.")
        if self.lobes not in LOBES:
            raise PlateLightError(f"Unknown glossy lobes {self.lobes!r}; use {' or '.join(map(repr, LOBES))}.")
        if self.sampling == "paper" and not 1 <= self.samples <= 50_000_000:
            raise PlateLightError(f"{{samples}} must be between 1 and 50,000,000, not {self.samples}.",
                                  samples="The number of samples")
        for name in ("glossy1_exponent", "glossy2_exponent"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0 <= value <= 100_000):
                raise PlateLightError(f"{name} must be a number between 0 and 100000, not {value}.")
        for name, height in self.heights.items():
            if name not in MAP_NAMES:
                raise PlateLightError(f"Unknown map {name!r}; maps are {', '.join(MAP_NAMES)}.")
            if not 2 <= int(height) <= 8192:
                raise PlateLightError(f"The {name} map height must be between 2 and 8192, not {height}.")

    def glossy_lobes(self) -> str:
        """The lobes the glossy maps are made with: the paper's sampling reproduces the paper
        (Phong lobes, glossy2 by spatial convolution); exact sampling the chosen ones."""
        return "phong" if self.sampling == "paper" else self.lobes

    def lobe_factors(self, name: str, lmax: int) -> np.ndarray:
        """The SH factors of map ``name``'s lobe (not the specular map's, which has none)."""
        if name != "diffuse" and self.glossy_lobes() == "ggx":
            return sh.ggx_lobe_factors(MAP_ROUGHNESS[name] ** 2, lmax)
        exponent = {"diffuse": 1.0, "glossy1": self.glossy1_exponent,
                    "glossy2": self.glossy2_exponent}[name]
        return sh.lobe_factors(float(exponent), lmax)

    def lobe_lmax(self, name: str, limit: int) -> int:
        """Degree at which map ``name``'s lobe is converged (at most ``limit``)."""
        if name == "diffuse":
            return min(DIFFUSE_LMAX_EXACT, limit)
        if self.glossy_lobes() == "ggx":
            return last_degree_above(sh.ggx_lobe_factors(MAP_ROUGHNESS[name] ** 2, min(limit, 256)),
                                      GGX_LOBE_CUTOFF)
        return lobe_lmax(getattr(self, f"{name}_exponent"), limit)


# Half-energy angle of each map's lobe (diffuse, glossy1, glossy2, specular) at the default
# exponents (design.md): 45, 22.2, 8.35, 0 degrees; the footprint rule reads them.
MAP_HALF_ANGLES = (lobe_half_angle(1.0), lobe_half_angle(MapSettings.glossy1_exponent),
                   lobe_half_angle(MapSettings.glossy2_exponent), 0.0)


@dataclasses.dataclass
class MapsResult:
    maps: dict                         # name -> float32 (h, 2h, 3)
    sh: np.ndarray                     # SH of the probe radiance, ((SH_JSON_LMAX+1)², 3)
    warnings: list                     # one sentence each (repaired pixels, clamped ringing)
    timings: dict                      # stage -> seconds
    stats: dict                        # e.g. negative texels clamped per map


def prepare_environment(env: np.ndarray, name: str = "environment map") -> tuple[np.ndarray, list]:
    """Validate a probe and repair what can be repaired, saying so: NaN/Inf pixels become 0 and
    negative values are clamped to 0 (radiance cannot be negative). Returns (float32 RGB, warnings)."""
    env = np.asarray(env)
    check_shape(env, name)
    if env.shape[0] > MAX_PROBE_HEIGHT:
        raise PlateLightError(f"The {name} is {env.shape[1]}×{env.shape[0]}; the largest supported "
                              f"probe is {2 * MAX_PROBE_HEIGHT}×{MAX_PROBE_HEIGHT}.")
    env = np.asarray(env[..., :3], dtype=np.float32)
    warnings = []
    if np.isfinite(env.min()) and np.isfinite(env.max()):     # fast path: nothing to repair
        bad = None
    else:
        bad = ~np.isfinite(env)
    if bad is not None:
        n = int(bad.any(axis=-1).sum())
        env = np.where(bad, np.float32(0), env)
        warnings.append(f"{n} pixel(s) of the {name} were NaN or infinite and were set to 0.")
    if env.min() < 0:
        n = int((env < 0).any(axis=-1).sum())
        env = np.maximum(env, 0)
        warnings.append(f"{n} pixel(s) of the {name} were negative and were clamped to 0.")
    return env, warnings


@lru_cache(maxsize=64)
def lobe_lmax(exponent: float, limit: int) -> int:
    """Degree beyond which every SH factor of the Phong lobe stays below LOBE_CUTOFF.

    Not the first small factor: for an even integer s the even factors above s vanish exactly
    while the odd ones only decay polynomially (s = 8: λ_10 = 0 but λ_11 ≈ −1e-4)."""
    return last_degree_above(sh.lobe_factors(float(exponent), min(limit, 256)), LOBE_CUTOFF)


def last_degree_above(factors: np.ndarray, cutoff: float) -> int:
    """The highest degree whose factor is at least ``cutoff`` in magnitude (0 if none)."""
    large = np.nonzero(np.abs(factors) >= cutoff)[0]
    return int(large[-1]) if large.size else 0


def _max_lmax(height: int) -> int:
    return max(2, height - 1)


def convolve_spatial(env: np.ndarray, exponent: float, height: int, source_height: int | None = None,
                     chunk: int = 256) -> np.ndarray:
    """Brute-force spatial convolution with the normalised Phong lobe (the paper's glossy2 route):
    every output texel sums the (downsampled) source weighted by lobe × texel solid angle."""
    if source_height is not None and source_height < env.shape[0]:
        env = downsample_area(env, source_height)
    hs, ws = env.shape[:2]
    src_dirs = texel_directions(hs, ws).reshape(-1, 3)
    src = (env.reshape(-1, 3).astype(np.float64) * texel_solid_angles(hs, ws).reshape(-1, 1))
    out_dirs = texel_directions(height, 2 * height).reshape(-1, 3)
    solid_angles = texel_solid_angles(hs, ws).reshape(-1)
    out = np.empty((out_dirs.shape[0], 3))
    for start in range(0, out_dirs.shape[0], chunk):
        lobe = np.maximum(out_dirs[start:start + chunk] @ src_dirs.T, 0.0) ** exponent
        # Normalise by the discrete lobe integral so a constant probe stays constant (the
        # midpoint sum of a narrow lobe on a coarse grid is off by ~0.6 % at s = 64, 128 rows).
        out[start:start + chunk] = (lobe @ src) / (lobe @ solid_angles)[:, None]
    return out.reshape(height, 2 * height, 3)


def compute_maps(env: np.ndarray, settings: MapSettings | None = None,
                 which=MAP_NAMES) -> MapsResult:
    """Compute the requested maps (and the probe's SH up to degree 15) from a lat-long probe."""
    settings = settings or MapSettings()
    settings.validate()
    which = tuple(which)
    unknown = [name for name in which if name not in MAP_NAMES]
    if unknown:
        raise PlateLightError(f"Unknown map(s) {unknown}; maps are {', '.join(MAP_NAMES)}.")
    timings = {}
    t0 = time.perf_counter()
    env, warnings = prepare_environment(env)
    heights = {**DEFAULT_HEIGHTS, **settings.heights}
    timings["prepare"] = time.perf_counter() - t0
    maps, stats = {}, {}
    limit = _max_lmax(env.shape[0])

    t0 = time.perf_counter()
    if settings.sampling == "exact":
        degrees = {name: settings.lobe_lmax(name, limit) for name in ("diffuse", "glossy1", "glossy2")}
        need = max([SH_JSON_LMAX] + [degrees[n] for n in which if n in degrees])
        coeffs = sh.project_exact(env, min(need, limit))
    else:
        degrees = {"diffuse": settings.paper_diffuse_lmax, "glossy1": settings.paper_glossy1_lmax}
        need = max(SH_JSON_LMAX, settings.paper_glossy1_lmax, settings.paper_diffuse_lmax)
        coeffs = sh.project_paper(env, need, settings.samples, settings.seed)
    timings["sh"] = time.perf_counter() - t0

    for name in which:
        t0 = time.perf_counter()
        height = int(heights[name])
        if name == "specular":
            image = downsample_area(env, height)
        elif name == "glossy2" and settings.sampling == "paper":
            image = convolve_spatial(env, settings.glossy2_exponent, height, source_height=2 * height)
        else:
            lmax = min(degrees[name], coeffs_lmax(coeffs))
            image = sh.synthesize(coeffs[: (lmax + 1) ** 2], height, settings.lobe_factors(name, lmax))
        negative = image < 0
        if negative.any():
            stats[f"{name}_negative_texels"] = int(negative.any(axis=-1).sum())
            stats[f"{name}_most_negative"] = float(image.min())
            image = np.maximum(image, 0)
        maps[name] = np.ascontiguousarray(image, dtype=np.float32)
        timings[name] = time.perf_counter() - t0
    if any(k.endswith("_negative_texels") for k in stats):
        parts = [f"{k[:-16]}: {v}" for k, v in stats.items() if k.endswith("_negative_texels")]
        warnings.append("SH ringing made some texels negative; they were clamped to 0 ("
                        + ", ".join(parts) + ").")
    # sh.json always holds degree 15; a tiny probe (lmax < 15) leaves the rest zero.
    sh_out = np.zeros(((SH_JSON_LMAX + 1) ** 2, 3))
    kept = min(sh_out.shape[0], coeffs.shape[0])
    sh_out[:kept] = coeffs[:kept]
    return MapsResult(maps=maps, sh=sh_out, warnings=warnings, timings=timings, stats=stats)


def coeffs_lmax(coeffs: np.ndarray) -> int:
    return int(round(np.sqrt(coeffs.shape[0]))) - 1


def map_filename(name: str, frame: int | None = None) -> str:
    """``diffuse.exr`` for a single-frame bake, ``diffuse_0001.exr`` for frame 1 of a sequence."""
    if name not in MAP_NAMES:
        raise ValueError(f"unknown map {name!r}")
    return f"{name}.exr" if frame is None else f"{name}_{int(frame):04d}.exr"


def write_maps(folder: str | os.PathLike, maps: dict, frame: int | None = None) -> dict:
    """Write each map as float32 EXR (atomically replacing older files). Returns name -> path."""
    folder = os.fspath(folder)
    paths = {}
    for name, image in maps.items():
        path = os.path.join(folder, map_filename(name, frame))
        write_exr(path, image)
        paths[name] = path
    return paths
