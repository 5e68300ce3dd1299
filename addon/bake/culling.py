"""Camera-frustum culling of an object's bounding sphere (is it ever on screen?).

The frustum is given the way Blender's ``Camera.view_frame()`` gives it: the four corners of
the film frame in camera space (camera looks along -Z). A perspective camera's side planes go
through the eye and two neighbouring corners; an orthographic camera's are parallel to -Z.
Planes are (normal, offset) with normal · p + offset >= 0 inside."""
from __future__ import annotations

import numpy as np


def frustum_planes(camera_to_world, frame_corners, clip_start: float, clip_end: float,
                   orthographic: bool = False) -> np.ndarray:
    """World-space planes (6, 4): [nx, ny, nz, d] with n·p + d >= 0 for points inside."""
    m = np.asarray(camera_to_world, dtype=np.float64).reshape(4, 4)
    corners = np.asarray(frame_corners, dtype=np.float64).reshape(4, 3)
    centre = corners.mean(axis=0)
    planes = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        if orthographic:
            n = np.cross(b - a, np.array([0.0, 0.0, -1.0]))
            point = a
        else:
            n = np.cross(a, b)
            point = np.zeros(3)
        n /= np.linalg.norm(n)
        if np.dot(n, centre - point) < 0:          # orient inwards whatever the corner order
            n = -n
        planes.append((n, -np.dot(n, point)))
    planes.append((np.array([0.0, 0.0, -1.0]), -clip_start))   # -z >= clip_start
    planes.append((np.array([0.0, 0.0, 1.0]), clip_end))       # -z <= clip_end
    # To world: a plane (n, d) in camera space is (R n, d - (R n)·t) in world space
    # (rigid part only: a scaled camera object still sees the same frustum shape).
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    t = m[:3, 3]
    out = np.empty((6, 4))
    for k, (n, d) in enumerate(planes):
        nw = rot @ n
        out[k, :3] = nw
        out[k, 3] = d - nw @ t
    return out


def sphere_in_frustum(planes: np.ndarray, centre, radius: float) -> bool:
    """Conservative test: False only when the sphere lies wholly outside one plane."""
    c = np.asarray(centre, dtype=np.float64)
    distances = planes[:, :3] @ c + planes[:, 3]
    return bool(np.all(distances >= -float(radius)))


def bounding_sphere(corners) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere holding the given points (e.g. the 8 bounding-box corners)."""
    pts = np.asarray(corners, dtype=np.float64).reshape(-1, 3)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    return centre, float(np.max(np.linalg.norm(pts - centre, axis=1))) if len(pts) else 0.0
