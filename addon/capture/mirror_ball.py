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
from ..ibl.equirect import row_elevations, row_solid_angles, texel_directions, texel_solid_angles


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
# A ball cut deeper than this is refused: past it a whole side of the world is missing.
MAX_CUT_USABLE = 0.25
# How the directions a cut ball does not show are filled.
FILLS = ("nearest", "black")


def find_ball(image: np.ndarray) -> Ball:
    """The mirror ball in a photo (8/16-bit BGR, or float radiance): see ball_finder."""
    from . import ball_finder

    return ball_of(ball_finder.find_ball(image))


def ball_of(fit) -> Ball:
    """The Ball of a ball_finder fit (an ellipse only where its axes differ)."""
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
    if 0 < cut_depth(ball, width, height) <= MAX_CUT:
        out.append("the ball touches the frame's edge: its outermost rim (directions almost straight behind "
                   "the ball) is filled from the nearest seen directions")
    return out


def cut_warning(ball: Ball, width: int, height: int, missing: float, fill: str) -> str | None:
    """What a ball cut by the frame leaves out of the probe (``missing``: share of the sphere's
    solid angle that no photo pixel shows), or None for a ball inside the frame."""
    depth = cut_depth(ball, width, height)
    if depth <= MAX_CUT:
        return None
    how = "filled from the nearest seen directions" if fill == "nearest" else "left black"
    return (f"the ball is cut by the frame ({100 * depth:.0f} % of its radius lies outside the photo): "
            f"{100 * missing:.1f} % of the probe's directions were not seen and are {how}")


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
    if depth > MAX_CUT_USABLE:
        raise PlateLightError(
            f"The ball is cut by the frame ({100 * depth:.0f} % of its radius lies outside the "
            f"{width}x{height} photo, more than {100 * MAX_CUT_USABLE:.0f} %); frame more of the ball.")


def aim_rotation(ball: Ball, intrinsics) -> np.ndarray:
    """The rotation taking the camera's axis (-Z) to the ray through the ball's centre: a ball
    off the photo's centre is seen from that side, and the orthographic model looks along the
    ray (measured on traced off-centre balls: SH9 error 12-36 % without, 5-9 % with)."""
    d = np.array([(ball.cx - intrinsics.cx) / intrinsics.fx, -(ball.cy - intrinsics.cy) / intrinsics.fy, -1.0])
    d /= np.linalg.norm(d)
    axis = np.cross([0.0, 0.0, -1.0], d)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + k + k @ k / (1.0 - d[2])         # Rodrigues; 1 + cos = 1 - d_z


def texel_supersampling(ball: Ball, height: int) -> int:
    """Sub-texels per probe texel side, so that a texel averages the photo pixels it covers
    rather than sampling one point (a small hot sun is otherwise caught or missed whole). At
    the ball's centre a texel spans ρ·π/(2·height) pixels; two samples a pixel, at most 8."""
    return int(np.clip(np.ceil(max(ball.radius, ball.ry) * np.pi / height), 1, 8))


def unwrap(image: np.ndarray, ball: Ball, height: int = 256, camera_to_world=None,
           reflectance: float = 1.0, rim_deg: float = 10.0, fill: str = "nearest"):
    """Lat-long probe (height x 2·height x C, float32) from a mirror-ball image (H, W, C) float.

    ``camera_to_world``: 3x3 (or 4x4) rotation of the camera that took the photo in Blender's
    camera convention (default: ``default_camera_rotation()``). Returns (probe, confidence) where
    confidence in [0, 1] falls to 0 in the blind spot behind the ball and where the frame cuts
    the ball; such unseen texels are filled as ``fill`` says (FILLS). Each texel is the
    solid-angle average of ``texel_supersampling`` ² sub-texels gathered from the photo."""
    probe, confidence, _ = unwrap_seen(image, ball, height, camera_to_world, reflectance, rim_deg, fill)
    return probe, confidence


def unwrap_seen(image: np.ndarray, ball: Ball, height: int = 256, camera_to_world=None,
                reflectance: float = 1.0, rim_deg: float = 10.0, fill: str = "nearest"):
    """``unwrap``, and the share of each texel's sub-texels that lie inside the photo (0 where
    the frame cuts the ball off)."""
    if height < 4:
        raise PlateLightError("The probe height must be at least 4 pixels.")
    if fill not in FILLS:
        raise PlateLightError(f"The fill must be one of {', '.join(FILLS)}, not '{fill}'.")
    rot = default_camera_rotation() if camera_to_world is None else np.asarray(camera_to_world, float)[:3, :3]
    img = np.asarray(image, dtype=np.float32)
    check_ball(ball, img.shape[1], img.shape[0])
    probe, seen = area_gather(img, ball, height, rot)
    probe = fill_unseen(probe / float(reflectance), seen > 0, fill)
    r_cam = texel_directions(height, 2 * height) @ rot
    angle_behind = np.degrees(np.arccos(np.clip(-r_cam[..., 2], -1, 1)))   # angle to d
    confidence = np.clip((180.0 - angle_behind) / rim_deg, 0, 1) * seen
    return probe.astype(np.float32), confidence.astype(np.float32), seen


def fill_unseen(probe: np.ndarray, seen: np.ndarray, fill: str) -> np.ndarray:
    """Texels no photo pixel showed: the nearest seen texel's value (lat-long distance) or 0."""
    import cv2

    if seen.all():
        return probe
    if fill == "black" or not seen.any():
        return np.where(seen[..., None], probe, 0)
    _, labels = cv2.distanceTransformWithLabels((~seen).astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    rows, cols = np.nonzero(seen)                      # label k: the k-th seen texel, row-major
    source = np.zeros(int(labels.max()) + 1, np.int64)
    source[labels[rows, cols]] = np.arange(rows.size)
    pick = source[labels]
    return np.where(seen[..., None], probe, probe[rows[pick], cols[pick]])


def unseen_share(seen: np.ndarray) -> float:
    """Share of the sphere's solid angle that no photo pixel shows, from ``unwrap_seen``'s seen."""
    sa = texel_solid_angles(*seen.shape)
    return float((sa * (1 - seen)).sum() / sa.sum())


# Sub-texels gathered at once: bounds the memory of a big photo's fine grid (~100 MB).
CHUNK_TEXELS = 1 << 22


def area_gather(img: np.ndarray, ball: Ball, height: int, rot: np.ndarray):
    """Each probe texel as the solid-angle weighted mean of its s x s sub-texels' photo
    values, s = texel_supersampling, and the share of them inside the photo (seen); gathered a
    band of rows at a time, in float32 with the lat-long's separable rows and columns
    (directions as full arrays cost 10x the remap)."""
    import cv2

    s = texel_supersampling(ball, height)
    fine = height * s
    azimuth = np.pi * ((np.arange(2 * fine) + 0.5) / fine - 1.0)
    # camera-frame direction R^T w = cos(el)·(cos az·R0 - sin az·R1) + sin(el)·R2, by component
    columns = (np.cos(azimuth)[:, None] * rot[0] - np.sin(azimuth)[:, None] * rot[1]).astype(np.float32)
    elevation = row_elevations(fine)
    weights = row_solid_angles(fine, 2 * fine)
    channels = img.shape[2] if img.ndim == 3 else 1
    out = np.empty((height, 2 * height, channels), np.float32)
    seen = np.empty((height, 2 * height), np.float32)
    height_px, width = img.shape[:2]
    band = max(1, CHUNK_TEXELS // (2 * fine * s))                 # probe rows a band
    for i0 in range(0, height, band):
        i1 = min(height, i0 + band)
        rows = slice(i0 * s, i1 * s)
        ce = np.cos(elevation[rows]).astype(np.float32)[:, None]
        se = np.sin(elevation[rows])[:, None] * rot[2]
        r = [ce * columns[:, k] + se[:, k:k + 1].astype(np.float32) for k in range(3)]
        # the normal halfway between r and the view ray's reverse (+Z), placed on the disc
        norm = np.sqrt(r[0] * r[0] + r[1] * r[1] + (r[2] + 1) ** 2)
        behind = norm < 1e-6                                   # r = -Z: the rim, any side
        norm = np.where(behind, np.float32(1), norm)
        map_x = ball.cx + ball.radius * np.where(behind, np.float32(1), r[0] / norm)
        map_y = ball.cy - ball.ry * r[1] / norm
        values = cv2.remap(img, map_x.astype(np.float32), map_y.astype(np.float32), cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE).reshape(i1 * s - i0 * s, 2 * fine, channels)
        # a sub-texel the frame cuts off the ball (beyond the edge pixels' centres) is not seen
        inside = (map_x >= -0.5) & (map_x <= width - 0.5) & (map_y >= -0.5) & (map_y <= height_px - 0.5)
        w = weights[rows].astype(np.float32)[:, None] * inside
        values *= w[..., None]
        box = (2 * height, i1 - i0)
        total = area_mean(w, box)
        seen[i0:i1] = total / area_mean(np.broadcast_to(weights[rows].astype(np.float32)[:, None], w.shape).copy(), box)
        out[i0:i1] = area_mean(values, box) / np.maximum(total, 1e-30)[..., None]
    return out, seen


def area_mean(values: np.ndarray, size) -> np.ndarray:
    """Box mean over whole s x s blocks (OpenCV's INTER_AREA at an integer factor)."""
    import cv2

    out = cv2.resize(values, size, interpolation=cv2.INTER_AREA)
    return out.reshape(size[1], size[0], -1) if values.ndim == 3 else out


def view_angle_deg(height: int, camera_to_world=None) -> np.ndarray:
    """Angle (deg) between each texel's direction and the direction towards the camera: 0 at
    the ball's centre, 180 at the blind spot behind it. Errors grow towards 180 (the rim)."""
    rot = default_camera_rotation() if camera_to_world is None else np.asarray(camera_to_world, float)[:3, :3]
    r_cam = texel_directions(height, 2 * height) @ rot
    return np.degrees(np.arccos(np.clip(r_cam[..., 2], -1, 1)))
