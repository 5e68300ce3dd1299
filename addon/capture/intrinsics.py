"""The camera's pinhole intrinsics (bpy-free): from a focal length, a calibration file, or
calibrated from ChArUco detections in the footage itself.

OpenCV's pixel coordinates put the centre of pixel (0, 0) at (0, 0), so the optical centre of
a W x H image is ((W-1)/2, (H-1)/2): that is the default principal point here."""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from ..errors import PlateLightError

@dataclasses.dataclass
class Intrinsics:
    """Pinhole camera in OpenCV pixel coordinates, with OpenCV's distortion coefficients."""
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_focal_px(cls, focal_px: float, width: int, height: int) -> "Intrinsics":
        if not np.isfinite(focal_px) or focal_px <= 0:
            raise PlateLightError(f"The focal length must be a positive number of pixels, not {focal_px}.")
        return cls(focal_px, focal_px, (width - 1) / 2.0, (height - 1) / 2.0)

    @classmethod
    def from_lens(cls, lens_mm: float, sensor_width_mm: float, width: int, height: int) -> "Intrinsics":
        if lens_mm <= 0 or sensor_width_mm <= 0:
            raise PlateLightError("The focal length and sensor width must be positive millimetres.")
        return cls.from_focal_px(lens_mm * width / sensor_width_mm, width, height)

    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], dtype=np.float64)

    def dist_array(self) -> np.ndarray:
        return np.asarray(self.dist, dtype=np.float64).reshape(-1)

    def to_json(self) -> dict:
        out = {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy}
        if np.any(self.dist_array() != 0):
            out["dist"] = [float(v) for v in self.dist_array()]
        return out


def load_calibration(path: str | os.PathLike) -> Intrinsics:
    """Read intrinsics from our JSON (``{"intrinsics": {fx, fy, cx, cy[, dist]}}``, e.g. a
    poses.json) or an OpenCV FileStorage YAML/XML with ``camera_matrix`` and
    ``distortion_coefficients``."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise PlateLightError(f"Calibration file not found: {path}")
    if path.lower().endswith(".json"):
        try:
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh)
            intr = data.get("intrinsics", data)
            return Intrinsics(float(intr["fx"]), float(intr["fy"]), float(intr["cx"]), float(intr["cy"]),
                              tuple(float(v) for v in intr.get("dist", (0,) * 5)))
        except (ValueError, KeyError, TypeError, AttributeError):
            raise PlateLightError(f"Calibration file has no intrinsics fx, fy, cx, cy: {path}") from None
    import cv2

    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    k = fs.getNode("camera_matrix").mat() if fs.isOpened() else None
    d = fs.getNode("distortion_coefficients").mat() if fs.isOpened() else None
    if k is None or k.shape != (3, 3):
        raise PlateLightError(f"Calibration file has no 3x3 camera_matrix: {path}")
    dist = tuple(float(v) for v in (d.reshape(-1) if d is not None else np.zeros(5)))
    return Intrinsics(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]), dist)


def calibrate_from_detections(detections: list, size: tuple[int, int]):
    """Intrinsics with OpenCV's five distortion coefficients from ChArUco detections
    (detection.Detection): (Intrinsics, calibration.Calibration)."""
    from .calibration import calibrate

    usable = [d for d in detections if d.kind == "charuco" and len(d.object_points) >= 6]
    cal = calibrate([d.object_points for d in usable], [d.image_points for d in usable], size)
    return Intrinsics(cal.fx, cal.fy, cal.cx, cal.cy, cal.dist), cal
