"""Chrome-ball brackets -> lat-long world probe: merge, find the ball, unwrap, check, repair."""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from ..errors import PlateLightError
from . import ball_finder, hdr_merge, mirror_ball


@dataclasses.dataclass
class ProbeResult:
    probe: np.ndarray                 # (H, 2H, 3) float32 lat-long, design.md's convention
    confidence: np.ndarray            # (H, 2H) 0 in the blind spot behind the ball
    ball: mirror_ball.Ball
    times: np.ndarray
    response: np.ndarray              # (256, 3) RGB inverse response, value 128 -> 1
    clipped: dict                     # solid angle and direction of texels clipped in every bracket
    warnings: list[str]
    repair_scale: float | None = None
    unseen: float = 0.0               # share of the sphere no photo pixel shows (a cut ball)
    candidates: list = dataclasses.field(default_factory=list)   # the finder's circles, best first
    photo: np.ndarray | None = None   # the bracket the circles are drawn on (BGR)

    def report(self) -> dict:
        return {
            "ball": self.ball.to_json(),
            "exposure_times": [float(t) for t in self.times],
            "clipped": self.clipped,
            "repair_scale": self.repair_scale,
            "unseen_share": round(self.unseen, 4),
            "candidates": [candidate_json(c) for c in self.candidates],
            "warnings": self.warnings,
            "response": np.round(self.response, 6).tolist(),
        }


def make_probe(paths, exposures=None, ball: mirror_ball.Ball | None = None, height: int = 256,
               camera_to_world=None, rotate_z_deg: float = 0.0, reflectance: float = 1.0,
               card_box=None, card_albedo: float = 0.18, card_normal=None,
               shared_response: bool = True, align_target=None, intrinsics=None,
               fill: str = "nearest") -> ProbeResult:
    """Brackets (files) -> probe. ``camera_to_world``: the photo camera's rotation in the
    scene's frame (e.g. from tracking a marker seen in the photo); ``rotate_z_deg`` then turns
    the probe about +Z (a user alignment). ``align_target`` (a tracking target, with
    ``intrinsics``): a marker or board seen in the brackets gives the camera rotation in
    the target's frame, i.e. the tracked scene's (it overrides ``camera_to_world``). ``card_box`` = (x0, y0, x1, y1) pixels of a grey card
    in the photos, used to repair light clipped in every bracket (hdr_merge.repair_clipped).
    ``intrinsics``: the photos' lens; given, the unwrap looks along the ray through the ball's
    centre (mirror_ball.aim_rotation) instead of the camera's axis. ``fill``: how the directions
    a ball cut by the frame does not show are filled (mirror_ball.FILLS)."""
    if not (np.isfinite(reflectance) and 0 < reflectance <= 1):
        raise PlateLightError("The ball's reflectance must be in (0, 1].")
    paths = [os.fspath(p) for p in paths]
    if len(paths) == 1:                           # one phone photo: an LDR probe, with a warning
        if exposures is not None and len(exposures) != 1:
            raise PlateLightError(f"{len(exposures)} exposure times were given for 1 photo.")
        photo, merged, t = hdr_merge.single_photo(paths[0], exposures[0] if exposures else None)
        images, times = [photo], np.array([t if t else 1.0])
        searched = photo
    else:
        images, times = hdr_merge.read_brackets(paths, exposures)
        merged = hdr_merge.merge(images, times, shared_response=shared_response)
        searched = merged.radiance
    candidates = []
    if ball is None:
        fit, candidates = ball_finder.find_ball_and_candidates(searched)
        ball = mirror_ball.ball_of(fit)
    h, w = merged.radiance.shape[:2]
    mirror_ball.check_ball(ball, w, h)
    if align_target is not None:
        camera_to_world = camera_from_target(images, align_target, intrinsics)
    rot = mirror_ball.default_camera_rotation() if camera_to_world is None else \
        np.asarray(camera_to_world, float)[:3, :3]
    rot = mirror_ball.rotation_z(rotate_z_deg) @ rot
    if intrinsics is not None:                   # the photo's lens known: look along the ball's ray
        rot = rot @ mirror_ball.aim_rotation(ball, intrinsics)
    # the clipped mask rides along as a fourth channel: one gather for both
    stacked = np.dstack([merged.radiance, merged.clipped.astype(np.float32)])
    unwrapped, confidence, seen = mirror_ball.unwrap_seen(stacked, ball, height, rot, fill=fill)
    probe = unwrapped[..., :3] / float(reflectance)
    clipped = unwrapped[..., 3] > 0.5
    summary = hdr_merge.clipped_region_summary(clipped)
    warnings = list(merged.warnings) + mirror_ball.ball_warnings(ball, w, h)
    unseen = mirror_ball.unseen_share(seen)
    cut = mirror_ball.cut_warning(ball, w, h, unseen, fill)
    if cut:
        warnings.append(cut)
    scale = None
    if card_box is not None:
        if not clipped.any():
            warnings.append("a grey card was given but nothing is clipped in every bracket; no repair needed")
        else:
            x0, y0, x1, y1 = (int(round(v)) for v in card_box)
            if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
                raise PlateLightError(f"The grey card box {tuple(card_box)} is not inside the {w}x{h} photos.")
            card = merged.radiance[y0:y1, x0:x1].reshape(-1, 3).mean(0)
            normal = summary["direction"] if card_normal is None else card_normal
            probe, scale = hdr_merge.repair_clipped(probe, clipped, card, card_albedo, normal)
            warnings.append(f"clipped light repaired from the grey card: x{scale:.2f} over its lower bound")
    return ProbeResult(probe, confidence, ball, times, merged.response, summary, warnings, scale, unseen,
                       candidates, images[len(images) // 2])


def candidate_json(fit) -> dict:
    """One of the finder's circles (ball_finder.BallFit) as the report writes it."""
    return {"cx": round(fit.cx, 2), "cy": round(fit.cy, 2), "rx": round(fit.rx, 2), "ry": round(fit.ry, 2),
            "confidence": round(fit.confidence, 3)}


def candidates_picture(photo: np.ndarray, candidates, used: mirror_ball.Ball | None = None,
                       longest: int = 1200) -> np.ndarray:
    """The photo (at most ``longest`` px) with the circle used in green and the finder's other
    candidates in orange, each labelled with its confidence: what to check when it is unsure."""
    import cv2

    photo = np.asarray(photo)
    if photo.dtype != np.uint8:                  # 16-bit or float: to 8-bit for the picture
        top = float(np.percentile(photo, 99.5)) or 1.0
        photo = np.clip(photo / top * 255, 0, 255).astype(np.uint8)
    if photo.ndim == 2:
        photo = cv2.cvtColor(photo, cv2.COLOR_GRAY2BGR)
    scale = min(1.0, longest / max(photo.shape[:2]))
    out = cv2.resize(photo, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) if scale < 1 else photo.copy()
    circles = [(c.cx, c.cy, c.rx, c.ry, c.confidence, False) for c in candidates
               if used is None or (c.cx, c.cy) != (used.cx, used.cy)]
    if used is not None:
        circles.append((used.cx, used.cy, used.radius, used.ry, used.confidence, True))
    for cx, cy, rx, ry, conf, chosen in circles:
        colour = (60, 220, 60) if chosen else (0, 150, 255)
        centre = (int(round((cx + 0.5) * scale - 0.5)), int(round((cy + 0.5) * scale - 0.5)))
        cv2.ellipse(out, centre, (max(1, int(round(rx * scale))), max(1, int(round(ry * scale)))), 0, 0, 360,
                    colour, 2, cv2.LINE_AA)
        label = "given" if conf is None else f"{conf:.2f}"
        cv2.putText(out, label, (centre[0] + 4, centre[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, 2, cv2.LINE_AA)
    return out


def camera_from_target(images, target, intrinsics) -> np.ndarray:
    """Camera_to_world of the ball photo from a marker/board seen in it: the brackets are tried
    from the middle exposure outwards and the first one where the target tracks is used."""
    from .detection import Tracker
    from .poses import cv_pose_to_blender

    if intrinsics is None:
        raise PlateLightError("Aligning on a marker needs the camera's {focal}.", focal="focal length")
    tracker = Tracker(target, intrinsics)
    middle = len(images) // 2
    order = sorted(range(len(images)), key=lambda i: abs(i - middle))
    for i in order:
        det = tracker.detect(images[i])
        if det.kind == "none":
            continue
        solved = tracker.solve(det)
        if solved is not None:
            return cv_pose_to_blender(solved[0], solved[1])
    raise PlateLightError(f"The alignment {target.dictionary} marker was not found in any bracket.")
