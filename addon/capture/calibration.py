"""Camera calibration from ChArUco detections: OpenCV's own model and solver, with the
uncertainty it reports and a warning (saying what to shoot) when the views do not pin the focal
length or the principal point down.

The fit is ``cv2.calibrateCameraExtended`` with OpenCV's default flags (fx, fy, cx, cy and the
five coefficients k1, k2, p1, p2, k3), so the same corners give the same intrinsics as
``cv2.calibrateCamera``; the standard deviations are OpenCV's (from the Jacobian at the
solution, scaled by the reprojection residual). Fixing k3 and the tangential terms, as this
project once did, moved the focal length by 20-45 % on OpenCV's own four tutorial photos (their
lens has k3 ~ 3): a few views cannot tell a wrong focal length from missing distortion terms.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError

INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
# Poorly constrained when the 1-sigma uncertainty exceeds these:
MAX_FOCAL_STD = 0.01             # of the focal length
MAX_CENTRE_STD = 0.01            # of the image width
MIN_TILT_DEG = 20.0              # no view's board turned further from the image plane than this
MIN_VIEWS = 3
ADVICE = ("shoot 10-20 views with the board filling much of the frame, tilted 30-45 degrees "
          "towards each side and corner in turn, and seen in every part of the picture")


@dataclasses.dataclass
class Calibration:
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple                  # k1, k2, p1, p2, k3 (OpenCV's order)
    std: dict                    # 1-sigma of each of INTRINSIC_NAMES
    rms_px: float
    views: int
    image_size: tuple
    tilt_deg: list               # per view: the board's angle to the image plane
    view_rms_px: list
    warnings: list

    def to_json(self) -> dict:
        k1, k2, p1, p2, k3 = (float(v) for v in self.dist)
        return {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy,
                "dist": [k1, k2, p1, p2, k3],
                "distortion": {"model": "opencv", "k1": k1, "k2": k2, "p1": p1, "p2": p2, "k3": k3},
                "std": {k: float(v) for k, v in self.std.items()},
                "rms_px": self.rms_px, "views": self.views, "image_size": list(self.image_size),
                "tilt_deg": [round(t, 2) for t in self.tilt_deg],
                "view_rms_px": [round(v, 4) for v in self.view_rms_px]}


def calibrate(object_points: list[np.ndarray], image_points: list[np.ndarray], size: tuple[int, int]) -> Calibration:
    """Intrinsics from views of a planar target: ``object_points`` (N, 3) in the target's
    plane z = 0, ``image_points`` (N, 2) pixels, ``size`` = (width, height)."""
    import cv2

    if len(object_points) < MIN_VIEWS:
        raise PlateLightError(
            f"Calibration needs the board in at least {MIN_VIEWS} frames with 6 corners each; found "
            f"{len(object_points)}: {ADVICE}.")
    obj = [np.asarray(o, np.float32).reshape(-1, 3) for o in object_points]
    img = [np.asarray(i, np.float32).reshape(-1, 1, 2) for i in image_points]
    rms, k, dist, rvecs, _, std_in, _, per_view = cv2.calibrateCameraExtended(
        obj, img, tuple(int(v) for v in size), None, None, flags=0)
    dist = np.asarray(dist, float).reshape(-1)[:5]
    std = dict(zip(INTRINSIC_NAMES, np.asarray(std_in, float).reshape(-1)[:9]))
    tilts = [float(np.degrees(np.arccos(abs(cv2.Rodrigues(r)[0][2, 2])))) for r in rvecs]
    cal = Calibration(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]),
                      tuple(float(v) for v in dist), std, float(rms), len(obj), tuple(size), tilts,
                      [float(v) for v in np.asarray(per_view).reshape(-1)], [])
    cal.warnings = weak_fit_warnings(cal)
    return cal


def weak_fit_warnings(cal: Calibration) -> list[str]:
    """What the views leave uncertain, and what to shoot instead."""
    problems = []
    f_rel = max(cal.std["fx"] / cal.fx, cal.std["fy"] / cal.fy)
    if not np.isfinite(f_rel) or f_rel > MAX_FOCAL_STD:
        problems.append(f"the focal length is only known to +-{100 * f_rel:.1f} %")
    c_rel = max(cal.std["cx"], cal.std["cy"]) / cal.image_size[0]
    if not np.isfinite(c_rel) or c_rel > MAX_CENTRE_STD:
        problems.append(f"the principal point is only known to +-{max(cal.std['cx'], cal.std['cy']):.1f} px")
    if max(cal.tilt_deg) < MIN_TILT_DEG:
        problems.append(f"every view is nearly face-on to the board (at most {max(cal.tilt_deg):.0f} degrees "
                        f"tilted), which cannot separate the focal length from the distance")
    if cal.views < 6:
        problems.append(f"only {cal.views} views were usable")
    if not problems:
        return []
    return [f"the calibration is weak: {'; '.join(problems)}. To fix it, {ADVICE}"]
