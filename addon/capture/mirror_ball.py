"""Mirror ball -> lat-long probe in design.md's convention (Blender's Environment Texture).

The ball photo is treated as orthographic (the camera far from the ball compared with its
radius): a pixel at normalised disc position (x, y) sees the normal n = (x, y, √(1-x²-y²)) in
the camera frame (Blender's: looks along -Z, +Y up) and reflects the view ray d = (0, 0, -1)
into r = d - 2(d·n)n. The unwrap gathers: for each probe texel direction w, r = R_c2wᵀ·w,
n ∝ r - d, and the photo is sampled at (cx + ρ·n_x, cy - ρ·n_y). The direction straight behind
the ball (r = d) maps to the rim: texels whose angle to d is below ``rim_deg`` are the blind
spot and get a low confidence."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError
from ..ibl.equirect import texel_directions


def default_camera_rotation() -> np.ndarray:
    """Camera at -Y looking horizontally towards +Y, +Z up (Blender's front view): the
    orientation assumed when the photo's camera direction is not given."""
    return np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


def rotation_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


@dataclasses.dataclass
class Ball:
    """The ball's outline in the photo, pixels (OpenCV's: centre of the top-left pixel at 0, 0).
    ``radius_y``: the vertical semi-axis when the outline is a slightly elliptical (None: a
    circle); ``confidence``: the share of the outline where the finder saw the rim (None: given)."""
    cx: float
    cy: float
    radius: float
    radius_y: float | None = None
    confidence: float | None = None

    @property
    def ry(self) -> float:
        return self.radius if self.radius_y is None else self.radius_y

    def to_json(self) -> dict:
        out = {"cx": self.cx, "cy": self.cy, "radius": self.radius}
        if self.radius_y is not None:
            out["radius_y"] = self.radius_y
        if self.confidence is not None:
            out["confidence"] = round(self.confidence, 3)
        return out


# The frame may clip this much of the ball's radius (the outermost rim reflects what lies
# almost straight behind the ball, the probe's blind spot) before the ball counts as cut.
MAX_CUT = 0.02


def find_ball(image: np.ndarray) -> Ball:
    """The mirror ball in a photo (8/16-bit BGR, or float radiance): see ball_finder."""
    from . import ball_finder

    fit = ball_finder.find_ball(image)
    return Ball(fit.cx, fit.cy, fit.rx, fit.ry if abs(fit.ry - fit.rx) > 1e-6 else None, fit.confidence)


def ball_warnings(ball: Ball, width: int, height: int) -> list[str]:
    """What the user should check about a found ball (unsure, touching the frame)."""
    from ..wording import Sentence
    from .ball_finder import BALL, HOW_TO_GIVE, UNSURE_CONFIDENCE

    out = []
    if ball.confidence is not None and ball.confidence < UNSURE_CONFIDENCE:
        out.append(Sentence(f"the ball's outline was seen on only {100 * ball.confidence:.0f} % of its rim, so "
                            f"the circle found (centre {ball.cx:.1f}, {ball.cy:.1f}, radius {ball.radius:.1f} px) "
                            f"is unsure: check it, or {HOW_TO_GIVE}", **BALL))
    if cut_depth(ball, width, height) > 0:
        out.append("the ball touches the frame's edge: its outermost rim (directions almost straight behind "
                   "the ball) is filled from the edge pixels")
    return out


def cut_depth(ball: Ball, width: int, height: int) -> float:
    """How far the frame cuts into the ball's outline, as a share of its radius (0: inside)."""
    rx, ry = ball.radius, ball.ry
    over = max(-0.5 - (ball.cx - rx), (ball.cx + rx) - (width - 0.5),
               -0.5 - (ball.cy - ry), (ball.cy + ry) - (height - 0.5), 0.0)
    return over / min(rx, ry)


def check_ball(ball: Ball, width: int, height: int) -> None:
    if not all(np.isfinite(v) for v in (ball.cx, ball.cy, ball.radius, ball.ry)):
        raise PlateLightError("The ball's circle must be finite numbers CX,CY,R.")
    if min(ball.radius, ball.ry) < 8:
        raise PlateLightError(f"The ball's radius ({ball.radius:.1f} px) is too small to unwrap.")
    depth = cut_depth(ball, width, height)
    if depth > MAX_CUT:
        raise PlateLightError(
            f"The ball is cut by the frame ({100 * depth:.0f} % of its radius lies outside the "
            f"{width}x{height} photo); frame the whole ball.")


def unwrap(image: np.ndarray, ball: Ball, height: int = 256, camera_to_world=None,
           reflectance: float = 1.0, rim_deg: float = 10.0):
    """Lat-long probe (height x 2·height x C, float32) from a mirror-ball image (H, W, C) float.

    ``camera_to_world``: 3x3 (or 4x4) rotation of the camera that took the photo in Blender's
    camera convention (default: ``default_camera_rotation()``). Returns (probe, confidence) where
    confidence in [0, 1] falls to 0 in the blind spot behind the ball."""
    import cv2

    if height < 4:
        raise PlateLightError("The probe height must be at least 4 pixels.")
    rot = default_camera_rotation() if camera_to_world is None else np.asarray(camera_to_world, float)[:3, :3]
    img = np.asarray(image, dtype=np.float32)
    check_ball(ball, img.shape[1], img.shape[0])
    dirs = texel_directions(height, 2 * height)
    r_cam = dirs @ rot                                      # R^T w, for every texel
    n = r_cam + np.array([0.0, 0.0, 1.0])
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(norm > 1e-9, n / np.maximum(norm, 1e-12), np.array([1.0, 0.0, 0.0]))
    map_x = (ball.cx + ball.radius * n[..., 0]).astype(np.float32)
    map_y = (ball.cy - ball.ry * n[..., 1]).astype(np.float32)
    probe = cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    if probe.ndim == 2:
        probe = probe[..., None]
    probe = probe / float(reflectance)
    angle_behind = np.degrees(np.arccos(np.clip(-r_cam[..., 2], -1, 1)))   # angle to d
    confidence = np.clip((180.0 - angle_behind) / rim_deg, 0, 1).astype(np.float32)
    return probe.astype(np.float32), confidence


def view_angle_deg(height: int, camera_to_world=None) -> np.ndarray:
    """Angle (deg) between each texel's direction and the direction towards the camera: 0 at
    the ball's centre, 180 at the blind spot behind it. Errors grow towards 180 (the rim)."""
    rot = default_camera_rotation() if camera_to_world is None else np.asarray(camera_to_world, float)[:3, :3]
    r_cam = texel_directions(height, 2 * height) @ rot
    return np.degrees(np.arccos(np.clip(r_cam[..., 2], -1, 1)))
