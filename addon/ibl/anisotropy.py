"""Anisotropic look-ups: a brushed lobe as a few look-ups of its narrow axis's lobe, spread along
the tangent.

The maps hold round lobes. Principled's anisotropic GGX has the alphas r^2 / aspect along the
tangent and r^2 aspect along the bitangent (aspect = sqrt(1 - 0.9 a)), so its highlight is a
streak. The shader reads the maps at the glossiness of the narrow axis (roughness sqrt(r^2 aspect))
in TAP_COUNT directions spread along the streak: direction + x_k * spread, with x_k the
equal-probability quantiles of GGX's slope distribution along one axis, scaled by the slope width
the narrow lobe lacks, sqrt(alpha_t^2 - alpha_b^2). Tilting the normal by a slope x along the
tangent T moves the mirror direction R of the view V by 2 x ((T.V) N + (N.V) T) to first order,
which is the spread's direction at any view.

On a bare metal sphere under the bundled HDRIs (brute-force anisotropic GGX as the truth, 15
materials; tests/bench/bench_anisotropy.py, docs/bench/anisotropy.md), five look-ups gained
1.43 dB on average over the round lobe, 5.1 dB on the benchmark's brushed metal (roughness 0.3,
anisotropy 0.8) under city.
The node groups (node_groups/sbrdf.py, probe_maps.py) build the same rule from these constants.
"""
from __future__ import annotations

import numpy as np

from .maps import glossiness_to_roughness, roughness_to_glossiness

# Principled BSDF's anisotropy: aspect = sqrt(1 - ASPECT_SCALE * a) (Cycles, MaterialX).
ASPECT_SCALE = 0.9
TAP_COUNT = 5


def _slope_quantiles(count: int) -> tuple:
    """Equal-probability quantiles of GGX's slope marginal along one axis, (1 + x^2)^(-3/2) / 2
    (alpha 1): its CDF is (1 + x / sqrt(1 + x^2)) / 2."""
    c = 2.0 * (np.arange(count) + 0.5) / count - 1.0
    return tuple(float(v) for v in c / np.sqrt(1.0 - c * c))


TAP_SLOPES = _slope_quantiles(TAP_COUNT)


def aspect(anisotropy):
    return np.sqrt(1.0 - ASPECT_SCALE * np.clip(anisotropy, 0.0, 1.0))


def narrow_glossiness(glossiness, anisotropy):
    """The glossiness of the lobe's narrow axis: unchanged at anisotropy 0."""
    # a difference of one rule, so anisotropy 0 gives back the glossiness exactly (as in nodes)
    roughness = glossiness_to_roughness(glossiness)
    return glossiness + (roughness_to_glossiness(roughness * np.sqrt(aspect(anisotropy)))
                         - roughness_to_glossiness(roughness))


def streak_slope(glossiness, anisotropy):
    """The slope width the narrow lobe lacks along the tangent: sqrt(alpha_t^2 - alpha_b^2)."""
    k = aspect(anisotropy)
    return glossiness_to_roughness(glossiness) ** 2 * np.sqrt(1.0 / k ** 2 - k ** 2)


def spread(normal, tangent, view, slope):
    """The look-ups' spread vector, 2 slope ((T.V) N + (N.V) T), per point (arrays (..., 3))."""
    tv = np.sum(tangent * view, axis=-1, keepdims=True)
    nv = np.sum(normal * view, axis=-1, keepdims=True)
    return 2.0 * np.asarray(slope)[..., None] * (tv * normal + nv * tangent)


def tap_directions(direction, spread_vector):
    """The TAP_COUNT unit look-up directions (each (..., 3)); equal weights."""
    taps = []
    for x in TAP_SLOPES:
        d = direction + x * spread_vector
        taps.append(d / np.linalg.norm(d, axis=-1, keepdims=True))
    return taps
