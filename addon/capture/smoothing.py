"""Camera paths in time (bpy-free): quaternions, Gaussian smoothing of poses, and the pose of a
frame between two tracked ones (slerp)."""
from __future__ import annotations

import numpy as np

def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    r = np.asarray(r, dtype=np.float64)
    tr = np.trace(r)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = np.zeros(4)
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def slerp(q0, q1, t: float) -> np.ndarray:
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    if np.dot(q0, q1) < 0:
        q1 = -q1
    d = float(np.clip(np.dot(q0, q1), -1, 1))
    if d > 0.9995:
        q = q0 + t * (q1 - q0)
    else:
        a = np.arccos(d)
        q = (np.sin((1 - t) * a) * q0 + np.sin(t * a) * q1) / np.sin(a)
    return q / np.linalg.norm(q)


def smooth_poses(frames: list[int], matrices: list[np.ndarray], sigma: float) -> list[np.ndarray]:
    """Gaussian smoothing (sigma in frames) of camera positions and orientations; the rotations
    are averaged as sign-aligned quaternions, which is accurate for the small spreads of a
    window of neighbouring frames. sigma <= 0 returns the poses unchanged."""
    if sigma <= 0 or len(matrices) < 3:
        return [np.array(m) for m in matrices]
    f = np.asarray(frames, dtype=np.float64)
    pos = np.array([m[:3, 3] for m in matrices])
    quats = np.array([matrix_to_quat(m[:3, :3]) for m in matrices])
    out = []
    for i in range(len(matrices)):
        w = np.exp(-0.5 * ((f - f[i]) / sigma) ** 2)
        w[np.abs(f - f[i]) > 3 * sigma] = 0
        signs = np.where(quats @ quats[i] < 0, -1.0, 1.0)
        q = (w[:, None] * signs[:, None] * quats).sum(0)
        m = np.eye(4)
        m[:3, :3] = quat_to_matrix(q)
        m[:3, 3] = (w[:, None] * pos).sum(0) / w.sum()
        out.append(m)
    return out


def interpolate_pose(f: int, f0: int, m0: np.ndarray, f1: int, m1: np.ndarray) -> np.ndarray:
    t = (f - f0) / float(f1 - f0)
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(slerp(matrix_to_quat(m0[:3, :3]), matrix_to_quat(m1[:3, :3]), t))
    m[:3, 3] = (1 - t) * m0[:3, 3] + t * m1[:3, 3]
    return m
