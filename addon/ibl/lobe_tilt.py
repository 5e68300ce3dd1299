"""The look-up tilt: where a glossy lobe seen at a grazing angle gets its light from.

A GGX lobe seen at a grazing angle is cut by the surface's horizon. The directions it keeps lie
on the normal's side of the mirror direction R, so its light comes from closer to N than R does.
The maps are blurred with whole lobes around R, so the shader looks them up along R tilted
towards N, halfway to the centroid of the kept lobe. On a bare metal sphere under the bundled
HDRIs that brought the four-map blend 0.0-3.2 dB nearer brute-force GGX at roughness 0.2-0.45;
the whole way overshoots (docs/decisions.md, "Look-up tilt").

The tilt is the offset s along N: direction = normalize(R + s N), tabulated per map over
mu = N.R, blended with the maps' tent weights. The node group (node_groups/sbrdf.py) draws each
map's row as a curve; tests/test_lobe_tilt.py derives the rows again by brute force.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .equirect import texel_directions, texel_solid_angles
from .ggx import smith_lambda
from .maps import MAP_NAMES, MAP_ROUGHNESS, tent_weights

# mu = N.R at which each map's offset is tabulated (denser towards grazing, where it changes).
MU = (0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75, 0.9, 0.97)
# s(mu) of each map's lobe (GGX at the map's roughness, maps.MAP_ROUGHNESS), from
# halfway_offset(); a mirror keeps R.
TILT = {
    "diffuse": (0.570, 0.558, 0.539, 0.509, 0.481, 0.454, 0.404, 0.359, 0.318, 0.281, 0.233, 0.191, 0.174),
    "glossy1": (0.355, 0.337, 0.311, 0.272, 0.238, 0.209, 0.162, 0.128, 0.102, 0.082, 0.058, 0.040, 0.032),
    "glossy2": (0.185, 0.159, 0.127, 0.090, 0.068, 0.053, 0.036, 0.026, 0.020, 0.015, 0.010, 0.005, 0.004),
    "specular": (0.0,) * len(MU),
}
# How far towards the kept lobe's centroid the look-up goes (1 overshot: docs/decisions.md).
TOWARDS_CENTROID = 0.5


@lru_cache(maxsize=1)
def _hemisphere(height: int):
    dirs = texel_directions(height, 2 * height).reshape(-1, 3)
    solid = texel_solid_angles(height, 2 * height).reshape(-1)
    above = dirs[:, 2] > 0
    return dirs[above], solid[above]


def kept_lobe_centroid(roughness: float, mu: float, height: int = 384) -> np.ndarray:
    """Unit centroid of the light a GGX surface (alpha = roughness², N = +Z) seen at N.V = mu
    reflects: D at the half vector times height-correlated Smith G2, over the directions above
    its horizon (brute force over a lat-long grid). The view lies in the XZ plane."""
    light, solid = _hemisphere(height)
    view = np.array([np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu])
    a2 = max(roughness, 1e-3) ** 4
    half = light + view
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    cos_h = half[:, 2]
    d = a2 / (np.pi * (cos_h * cos_h * (a2 - 1.0) + 1.0) ** 2)

    weight = d / (1.0 + smith_lambda(a2, mu) + smith_lambda(a2, light[:, 2])) * solid
    centroid = (weight[:, None] * light).sum(axis=0)
    return centroid / np.linalg.norm(centroid)


def halfway_offset(roughness: float, mu: float, height: int = 384) -> float:
    """The offset s along N that tilts R (elevation asin mu above the surface) a fraction
    TOWARDS_CENTROID of the way to kept_lobe_centroid()'s elevation."""
    if roughness <= 0.0:
        return 0.0
    mu = max(mu, 1e-3)
    elevation = np.arcsin(mu)
    centroid = np.arcsin(np.clip(kept_lobe_centroid(roughness, mu, height)[2], -1.0, 1.0))
    target = elevation + TOWARDS_CENTROID * max(centroid - elevation, 0.0)
    return float(np.cos(elevation) * np.tan(target) - np.sin(elevation))


def tilt_offset(glossiness, mu) -> np.ndarray:
    """s for map glossiness n' and mu = N.R: each map's row interpolated in mu, blended with the
    maps' tent weights, as the node group computes it."""
    mu = np.clip(np.asarray(mu, dtype=np.float64), 0.0, 1.0)
    return sum(weight * np.interp(mu, MU, TILT[name])
               for name, weight in zip(MAP_NAMES, tent_weights(glossiness)))


def tilted(direction: np.ndarray, normal: np.ndarray, glossiness) -> np.ndarray:
    """Unit look-up directions: ``direction`` (unit, ..., 3) tilted towards ``normal``."""
    mu = np.clip((direction * normal).sum(axis=-1), 0.0, 1.0)
    out = direction + tilt_offset(glossiness, mu)[..., None] * normal
    return out / np.linalg.norm(out, axis=-1, keepdims=True)
