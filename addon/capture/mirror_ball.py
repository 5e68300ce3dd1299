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
    cx: float
    cy: float
    radius: float


def find_ball(image: np.ndarray) -> Ball:
    """Find the ball's outline in an 8-bit (or float) image: Hough circles on the strongest
    edges, then a least-squares circle fit to sub-pixel edge points along radial profiles."""
    import cv2

    from .detection import to_gray8

    img = np.asarray(image)
    if np.issubdtype(img.dtype, np.floating):
        lum = np.maximum(np.nan_to_num(img[..., :3] if img.ndim == 3 else img), 0)
        lum = lum.mean(axis=-1, dtype=np.float32) if lum.ndim == 3 else lum.astype(np.float32)
        few = lum[::4, ::4]                             # percentiles from a subsample: 16x faster
        # Hough on log luminance (the outline shows in bright and dark surroundings alike)...
        floor = np.float32(np.percentile(few, 1) + 1e-8)
        log = np.log2(np.maximum(lum, floor))
        lo, hi = np.percentile(np.log2(np.maximum(few, floor)), [1, 99.5])
        gray = np.clip((log - lo) * np.float32(255.0 / max(hi - lo, 1e-6)), 0, 255)
        # ...the sub-pixel edge in linear light, where a blurred step is symmetric (in log or
        # gamma space its steepest point slides ~1 px towards the dark side).
        linear = np.clip(lum * np.float32(255.0 / max(np.percentile(few, 99), 1e-12)), 0, 380)
    else:
        from ..imaging import SRGB8_TO_LINEAR

        gray8 = to_gray8(img)
        gray = gray8.astype(np.float32)
        linear = SRGB8_TO_LINEAR[gray8]
    # Hough on at most ~1000 px (the refinement below restores full-resolution accuracy).
    shrink = max(1, int(np.ceil(max(gray.shape) / 1000)))
    if shrink > 1:
        gray = cv2.resize(gray, (gray.shape[1] // shrink, gray.shape[0] // shrink), interpolation=cv2.INTER_AREA)
    h, w = gray.shape
    blur = cv2.GaussianBlur(gray, (0, 0), 1.5).astype(np.uint8)
    circles = cv2.HoughCircles(blur, cv2.HOUGH_GRADIENT_ALT, dp=1.5, minDist=min(h, w) / 4,
                               param1=60, param2=0.75, minRadius=int(min(h, w) * 0.08),
                               maxRadius=int(min(h, w) * 0.5))
    if circles is None or len(circles) == 0:
        raise PlateLightError("No mirror ball was found in the brackets; give its circle with {ball}.",
                              ball="its centre and radius in pixels")
    # HOUGH_GRADIENT_ALT sorts by quality; take the best one and refine it.
    cx, cy, r = (float(v) for v in circles.reshape(-1, 3)[0])
    if shrink > 1:   # centre of a shrunk pixel -> full-resolution pixel coordinates
        cx, cy, r = (cx + 0.5) * shrink - 0.5, (cy + 0.5) * shrink - 0.5, r * shrink
    return refine_circle(linear, Ball(cx, cy, r))


def refine_circle(gray: np.ndarray, ball: Ball, reach: float = 0.08) -> Ball:
    """Sub-pixel circle from the *outermost* strong edge on 720 rays around the guess, fitted by
    least squares with outlier rejection. A mirror ball's outline is weaker than the compressed
    reflections just inside its rim (measured on Cycles renders: the strongest-gradient circle
    sits 1.5-2 px inside the true rim), but it is the last edge before the smooth background."""
    import cv2

    img = cv2.GaussianBlur(np.asarray(gray, dtype=np.float32), (0, 0), 0.7)
    theta = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    step = 0.25
    radii = ball.radius * (1 - reach) + np.arange(0, 2 * reach * ball.radius + 4, step)
    xs = ball.cx + np.cos(theta)[:, None] * radii[None, :]
    ys = ball.cy + np.sin(theta)[:, None] * radii[None, :]
    prof = cv2.remap(img, xs.astype(np.float32), ys.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    grad = np.abs(np.gradient(prof, axis=1))
    pts = []
    for a in range(len(theta)):
        g = grad[a]
        if not np.all(np.isfinite(g)):
            continue
        strong = g > 0.35 * g.max()
        if g.max() < 0.5 or not strong.any():
            continue
        k = int(np.nonzero(strong)[0][-1])              # outermost strong sample (outer flank)...
        while k > 0 and g[k - 1] >= g[k]:               # ...climbed inwards to its peak
            k -= 1
        if 0 < k < len(g) - 1:
            den = g[k - 1] - 2 * g[k] + g[k + 1]
            frac = 0.5 * (g[k - 1] - g[k + 1]) / den if abs(den) > 1e-9 else 0.0
            r = radii[k] + float(np.clip(frac, -0.5, 0.5)) * step
            pts.append((ball.cx + np.cos(theta[a]) * r, ball.cy + np.sin(theta[a]) * r))
    if len(pts) < 60:
        return ball
    p = np.asarray(pts)
    keep = np.ones(len(p), bool)
    for _ in range(5):
        a_ = np.stack([p[keep, 0], p[keep, 1], np.ones(keep.sum())], axis=1)
        sol, *_ = np.linalg.lstsq(a_, (p[keep] ** 2).sum(1), rcond=None)
        cx, cy = sol[0] / 2, sol[1] / 2
        r = float(np.sqrt(sol[2] + cx ** 2 + cy ** 2))
        res = np.abs(np.hypot(p[:, 0] - cx, p[:, 1] - cy) - r)
        mad = np.median(res[keep]) + 1e-6
        keep = res < max(3 * 1.4826 * mad, 0.2)
    if not np.isfinite(r) or abs(r - ball.radius) > reach * ball.radius:
        return ball
    return Ball(float(cx), float(cy), r)


def check_ball(ball: Ball, width: int, height: int) -> None:
    if ball.radius < 8:
        raise PlateLightError(f"The ball's radius ({ball.radius:.1f} px) is too small to unwrap.")
    if (ball.cx - ball.radius < -1 or ball.cy - ball.radius < -1 or ball.cx + ball.radius > width
            or ball.cy + ball.radius > height):
        raise PlateLightError("The ball's circle reaches outside the image; frame the whole ball.")


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
    map_y = (ball.cy - ball.radius * n[..., 1]).astype(np.float32)
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
