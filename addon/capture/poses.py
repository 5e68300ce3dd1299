"""Camera poses between OpenCV's convention and Blender's (bpy-free).

OpenCV: world -> camera (rvec, tvec), camera x right, y down, looking along +z. Blender: row-major
4x4 camera_to_world, camera looking along its -Z with +Y up (design.md)."""
from __future__ import annotations

import numpy as np

# OpenCV camera (x right, y down, looks along +z) -> Blender camera (x right, y up, looks along -z)
CV_TO_BLENDER_CAMERA = np.diag([1.0, -1.0, -1.0])

def cv_pose_to_blender(rvec, tvec) -> np.ndarray:
    """World->OpenCV-camera pose (rvec, tvec) -> Blender camera_to_world 4x4."""
    import cv2

    r, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    m = np.eye(4)
    m[:3, :3] = r.T @ CV_TO_BLENDER_CAMERA
    m[:3, 3] = -r.T @ np.asarray(tvec, dtype=np.float64).reshape(3)
    return m


def blender_to_cv_pose(camera_to_world: np.ndarray):
    """Inverse of cv_pose_to_blender: (R world->cv camera, t)."""
    m = np.asarray(camera_to_world, dtype=np.float64)
    r = (m[:3, :3] @ CV_TO_BLENDER_CAMERA).T
    return r, -r @ m[:3, 3]


def rotation_error_deg(r_a: np.ndarray, r_b: np.ndarray) -> float:
    """Angle of the rotation taking r_b to r_a, in degrees."""
    c = (np.trace(np.asarray(r_a)[:3, :3].T @ np.asarray(r_b)[:3, :3]) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))
