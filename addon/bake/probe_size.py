"""How large a mirror-like object's probe must be: sized to the object on screen.

A mirror sphere D pixels across shows the whole panorama on its disk, so a probe much smaller
than D blurs its reflection. Twice the diameter is enough and more buys nothing, while the
bake's time grows with the probe's area (docs/decisions.md, "A mirror's probe is sized to the
mirror on screen").
Objects that only need blurred maps (diffuse, glossy) keep the scene's Probe Height.

The projection follows Blender's ``Camera.view_frame()``: the film frame's four corners in
camera space (camera looks along -Z), at depth |z| for a perspective camera."""
from __future__ import annotations

import numpy as np

PIXELS_PER_DIAMETER = 2.0
DEFAULT_MAX_HEIGHT = 1024


def projected_extent(camera_to_world, frame_corners, resolution_x: float, points,
                     orthographic: bool = False) -> float:
    """The larger side in pixels of the film-plane box around world ``points`` (an object's surface
    points: its silhouette's extent, not a bounding sphere's, which overstates a ball by √3);
    infinity when a point lies at or behind the camera."""
    m = np.asarray(camera_to_world, dtype=np.float64).reshape(4, 4)
    corners = np.asarray(frame_corners, dtype=np.float64).reshape(4, 3)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    local = (np.asarray(points, dtype=np.float64).reshape(-1, 3) - m[:3, 3]) @ rot
    film_width = float(corners[:, 0].max() - corners[:, 0].min())
    if film_width <= 0 or len(local) == 0:
        return 0.0
    if orthographic:
        xy = local[:, :2] * (resolution_x / film_width)
    else:
        depth = -local[:, 2]
        if depth.min() <= 1e-9:
            return float("inf")
        focal_px = resolution_x * abs(float(corners[0, 2])) / film_width
        xy = local[:, :2] * (focal_px / depth)[:, None]
    return float((xy.max(axis=0) - xy.min(axis=0)).max())


def auto_probe_height(diameter_px: float, minimum: int, maximum: int = DEFAULT_MAX_HEIGHT) -> int:
    """The probe height for an object ``diameter_px`` across on screen: the power of two at or above
    PIXELS_PER_DIAMETER × diameter, within [minimum, maximum] (maximum wins)."""
    want = PIXELS_PER_DIAMETER * float(diameter_px)
    height = 1 << max(0, int(np.ceil(np.log2(want)))) if np.isfinite(want) and want > 1 else 1
    if not np.isfinite(want):
        height = maximum
    return int(min(max(height, minimum), maximum))


# A small probe's noise reaches a glossy reflection whole, so a probe below SAMPLE_ROWS rows gets
# as many samples as keep its rays at a SAMPLE_ROWS probe's, at most MAX_SAMPLE_FACTOR times Probe
# Samples (docs/decisions.md, "Probe samples"); larger (mirror) probes keep Probe Samples.
SAMPLE_ROWS = 128
MAX_SAMPLE_FACTOR = 2


def samples_for(probe_samples: int, height: int) -> int:
    """Cycles samples per pixel for a probe ``height`` rows high, given the scene's Probe Samples."""
    factor = min(max((SAMPLE_ROWS / max(int(height), 1)) ** 2, 1.0), MAX_SAMPLE_FACTOR)
    return max(1, int(round(int(probe_samples) * factor)))
