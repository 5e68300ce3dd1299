"""How much of its own sky an object's surface hides from itself.

The SBRDF shades every point of an object from one probe at its centre, rendered without the
object (the paper's probe), so it never shadows itself: where a surface occludes itself (a hollow,
a fold, an ear against a head) the SBRDF is too bright and the path-traced twin is right. The
measure is the object's ambient occlusion by itself: the mean over its surface (area-weighted) of
the cosine-weighted fraction of each point's hemisphere that the object blocks. A convex object
scores exactly 0. The ray casting is the caller's (operators/composite/self_occlusion.py)."""
from __future__ import annotations

import numpy as np

SAMPLE_POINTS = 256          # points over the surface
RAYS_PER_POINT = 32          # 8192 rays: the fraction's standard error is below 0.005
# An object whose surface hides more of its own sky than this is shaded path-traced
# (docs/decisions.md, "A CG that shadows itself path-traced")
SELF_SHADOWING_AT = 0.002
SEED = 0                     # the same answer at every setup of the same object


def surface_samples(triangles: np.ndarray, count: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """(points, unit face normals), each (count, 3): uniform over the area of ``triangles``
    ((T, 3, 3), world space); empty where the triangles have no area."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    if not np.isfinite(area).all() or area.sum() <= 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    pick = rng.choice(len(area), size=count, p=area / area.sum())
    u, v = rng.random((2, count))
    folded = u + v > 1.0                 # the square's far half folded back onto the triangle
    u[folded], v[folded] = 1.0 - u[folded], 1.0 - v[folded]
    points = a[pick] + u[:, None] * (b - a)[pick] + v[:, None] * (c - a)[pick]
    return points, cross[pick] / area[pick, None]


def cosine_directions(normals: np.ndarray, count: int, rng) -> np.ndarray:
    """(N, count, 3) unit directions about each normal, cosine-weighted (Malley's method), so the
    fraction of them that hit is the occlusion the diffuse light sees."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    tangent = np.cross(normals, helper)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(normals, tangent)
    u1, u2 = rng.random((2, len(normals), count))
    radius, angle = np.sqrt(u1), 2.0 * np.pi * u2
    x, y, z = radius * np.cos(angle), radius * np.sin(angle), np.sqrt(np.clip(1.0 - u1, 0.0, 1.0))
    return (x[..., None] * tangent[:, None] + y[..., None] * bitangent[:, None]
            + z[..., None] * normals[:, None])


def rays(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origins (N, 3), directions (N, RAYS_PER_POINT, 3)) to cast against the object itself;
    origins sit a hair above the surface so that no ray hits the face it starts on."""
    rng = np.random.default_rng(SEED)
    points, normals = surface_samples(triangles, SAMPLE_POINTS, rng)
    if not len(points):
        return points, np.zeros((0, RAYS_PER_POINT, 3))
    size = float(np.linalg.norm(np.ptp(triangles.reshape(-1, 3), axis=0)))
    return points + normals * (1e-5 * size), cosine_directions(normals, RAYS_PER_POINT, rng)


def occluded_fraction(hits: np.ndarray) -> float:
    """The self-occlusion from the rays' hits (True where a ray met the object); 0 without rays."""
    return float(np.mean(hits)) if np.size(hits) else 0.0
