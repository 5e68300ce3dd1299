"""Camera tracking through footage (bpy-free): every frame is searched for the target
(detection.py), the camera is given or calibrated (intrinsics.py), poses are solved, converted
to Blender's convention (poses.py), smoothed and filled in where tracking was lost
(smoothing.py). Poses come out as row-major 4x4 camera_to_world matrices (design.md)."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import PlateLightError
from ..footage import iter_frames
from .detection import MIN_MARKER_SIDE_PX, Detection, Tracker, to_gray8
from .intrinsics import Intrinsics, calibrate_from_detections
from .poses import cv_pose_to_blender
from .smoothing import interpolate_pose, smooth_poses
from .targets import CharucoTarget, get_dictionary

@dataclasses.dataclass
class TrackResult:
    image_size: tuple[int, int]
    intrinsics: Intrinsics
    frames: list[dict]
    target_extent: tuple[float, float]
    warnings: list[str] = dataclasses.field(default_factory=list)
    calibration: dict | None = None           # calibration.Calibration.to_json() when calibrated

    @property
    def tracked_count(self) -> int:
        return sum(1 for f in self.frames if f["tracked"])

    def to_json(self) -> dict:
        return {
            "image_size": list(self.image_size),
            "intrinsics": self.intrinsics.to_json(),
            "target_size": list(self.target_extent),
            "frames": self.frames,
            "warnings": self.warnings,
            **({"calibration": self.calibration} if self.calibration else {}),
        }


def _wrong_dictionary_hint(images: list[np.ndarray], chosen: str) -> str | None:
    """Name of another dictionary whose markers appear in ``images``, if any."""
    import cv2

    names = [n for n in ("DICT_4X4_50", "DICT_5X5_50", "DICT_6X6_50", "DICT_7X7_50",
                         "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11", "DICT_4X4_1000",
                         "DICT_5X5_1000", "DICT_6X6_1000", "DICT_7X7_1000")
             if n.upper() != chosen.upper()]
    for name in names:
        det = cv2.aruco.ArucoDetector(get_dictionary(name), cv2.aruco.DetectorParameters())
        for img in images:
            _, ids, _ = det.detectMarkers(img)
            if ids is not None and len(ids) > 0:
                return name
    return None


def track(source, target, intrinsics: Intrinsics | None = None, focal_px: float | None = None,
          lens_mm: float | None = None, sensor_width_mm: float = 36.0, calibrate: bool = False,
          smooth_sigma: float = 0.0, lost: str = "interpolate", progress=None) -> TrackResult:
    """Track ``target`` through a folder of frames or a video.

    Intrinsics: given, or from ``focal_px``, or from ``lens_mm``/``sensor_width_mm``, or
    (``calibrate=True``, ChArUco boards only) calibrated from the frames themselves.
    ``lost``: "interpolate" (slerp between tracked neighbours, hold at the ends) or "skip"
    (no pose for that frame). ``progress(i)`` is called after each frame."""
    if lost not in ("interpolate", "skip"):
        raise PlateLightError(f"Lost-frame handling must be 'interpolate' or 'skip', not '{lost}'.")
    if calibrate and not isinstance(target, CharucoTarget):
        raise PlateLightError("Calibration from the frames needs a ChArUco board, not a single marker.")
    if intrinsics is None and focal_px is None and lens_mm is None and not calibrate:
        raise PlateLightError("Give the camera: a {focal} or a {calibration}.", focal="focal length",
                              calibration="calibration file")
    tracker = Tracker(target)
    detections: list[tuple[int, Detection]] = []
    size = None
    samples_for_hint = []
    for frame, image in iter_frames(source):
        h, w = image.shape[:2]
        if size is None:
            size = (w, h)
        elif size != (w, h):
            raise PlateLightError(f"Frame {frame} is {w}x{h} but the first frame is {size[0]}x{size[1]}.")
        det = tracker.detect(image)
        if det.kind == "none" and len(samples_for_hint) < 5:
            samples_for_hint.append(to_gray8(image))
        detections.append((frame, det))
        if progress:
            progress(frame)
    found = [(f, d) for f, d in detections if d.kind != "none"]
    if not found:
        if any(d.too_small for _, d in detections):
            side = max(d.side_px for _, d in detections)
            raise PlateLightError(
                f"The marker is too small in the image to track ({side:.0f} px a side; at least "
                f"{MIN_MARKER_SIDE_PX:.0f} px needed): film it closer or print it larger.")
        other = _wrong_dictionary_hint(samples_for_hint, target.dictionary)
        if other:
            raise PlateLightError(
                f"No {target.dictionary} marker was found, but {other} markers were: wrong {{dictionary}}?",
                dictionary="marker dictionary")
        if any(d.rejected > 0 for _, d in detections):
            raise PlateLightError(
                "Marker-like squares were seen but none could be decoded in any frame: the marker "
                "is too small, blurred or out of focus (or the dictionary is wrong).")
        raise PlateLightError(f"No {target.dictionary} marker was found in any of the {len(detections)} frames.")

    warnings = []
    cal = None
    if calibrate:
        intrinsics, cal = calibrate_from_detections([d for _, d in found], size)
        warnings.append(f"calibrated from {cal.views} frames, RMS reprojection {cal.rms_px:.3f} px, "
                        f"fx {intrinsics.fx:.1f} +- {cal.std['fx']:.1f}, fy {intrinsics.fy:.1f} +- "
                        f"{cal.std['fy']:.1f}, cx {intrinsics.cx:.1f} +- {cal.std['cx']:.1f}, "
                        f"cy {intrinsics.cy:.1f} +- {cal.std['cy']:.1f} px")
        warnings.extend(cal.warnings)
    elif intrinsics is None:
        intrinsics = (Intrinsics.from_focal_px(focal_px, *size) if focal_px is not None
                      else Intrinsics.from_lens(lens_mm, sensor_width_mm, *size))
    tracker.intrinsics = intrinsics
    if np.any(intrinsics.dist_array() != 0):
        warnings.append("the poses use the calibrated lens distortion: in Blender the CG is rendered "
                        "undistorted with overscan and redistorted onto the plate (platelight.setup_lens)")

    solved = {}
    for frame, det in found:
        res = tracker.solve(det)
        if res is not None:
            solved[frame] = (cv_pose_to_blender(res[0], res[1]), res[2])
    tracked_frames = sorted(solved)
    if not tracked_frames:
        raise PlateLightError("The marker was found but no camera pose could be solved in any frame.")
    smoothed = smooth_poses(tracked_frames, [solved[f][0] for f in tracked_frames], smooth_sigma)
    poses = dict(zip(tracked_frames, smoothed))

    frames = []
    lost_frames = []
    for frame, _ in detections:
        if frame in poses:
            frames.append({"frame": frame, "tracked": True,
                           "camera_to_world": poses[frame].tolist(),
                           "reprojection_px": round(solved[frame][1], 4)})
            continue
        lost_frames.append(frame)
        entry = {"frame": frame, "tracked": False, "camera_to_world": None, "reprojection_px": None}
        if lost == "interpolate":
            before = [f for f in tracked_frames if f < frame]
            after = [f for f in tracked_frames if f > frame]
            if before and after:
                m = interpolate_pose(frame, before[-1], poses[before[-1]], after[0], poses[after[0]])
            else:
                m = poses[before[-1] if before else after[0]]
            entry["camera_to_world"] = m.tolist()
            entry["interpolated"] = True
        frames.append(entry)
    if lost_frames:
        warnings.append(f"tracking lost in {len(lost_frames)} of {len(detections)} frames: "
                        f"{_ranges(lost_frames)} ({'interpolated' if lost == 'interpolate' else 'left unkeyed'})")
    return TrackResult(size, intrinsics, frames, target.extent, warnings,
                       cal.to_json() if cal is not None else None)


def _ranges(frames: list[int]) -> str:
    parts, start, prev = [], frames[0], frames[0]
    for f in frames[1:] + [None]:
        if f is not None and f == prev + 1:
            prev = f
            continue
        parts.append(str(start) if start == prev else f"{start}-{prev}")
        if f is not None:
            start = prev = f
    return ", ".join(parts)
