"""A moving object's probe reused for the frames in which it has moved little since its last
render (Probe Reuse, off by default): over a frame-range bake a probe is rendered again only once
the object has travelled or turned by more than a fraction of its size (or anything else it sees
changed). The reused frame keeps the rendered frame's centre in its record, so the parallax
look-ups still start from where the panorama was taken; what goes stale is only how the object itself shows in its own probe (its
shadow on the floor) and the irradiance grid's box, both by at most that fraction."""
from __future__ import annotations

import numpy as np

# Off: at 0.25 bounding radii the rolling sphere of docs/bench/motion_320x180.md was 2.0 s a frame
# faster (4.05 against 6.05) but lost 3.3 dB on the object (its own shadow in its probe left
# behind), below the catcher's; a heavy probe (a mirror sized to the screen) may want it
DEFAULT_TOLERANCE = 0.0


def moved(points, origin, rendered_points, rendered_origin, radius) -> float:
    """How far an object has moved since its probe was rendered, in bounding radii: the larger of
    its probe centre's travel and its surface's travel about its centroid (turning, deforming).
    Infinite where the surfaces do not correspond point for point (another vertex count)."""
    points, rendered_points = np.asarray(points, dtype=np.float64), np.asarray(rendered_points, dtype=np.float64)
    if points.shape != rendered_points.shape or not points.size or not radius > 0:
        return float("inf")
    travel = float(np.linalg.norm(np.asarray(origin, dtype=np.float64) - np.asarray(rendered_origin, dtype=np.float64)))
    about = (points - points.mean(axis=0)) - (rendered_points - rendered_points.mean(axis=0))
    turn = float(np.linalg.norm(about, axis=1).max())
    return max(travel, turn) / radius


def reusable(points, origin, rendered, radius, tolerance) -> bool:
    """Can the frame reuse ``rendered`` (the last rendered frame's points and origin)?"""
    if tolerance <= 0 or rendered is None:
        return False
    return moved(points, origin, rendered["points"], rendered["origin"], radius) <= tolerance
