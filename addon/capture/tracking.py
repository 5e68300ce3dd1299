"""Camera tracking from ArUco markers and ChArUco boards (OpenCV 4.11), bpy-free.

World frame (design.md): the target's own, origin at its centre, target in z = 0, +Z out of the
printed face, +X right and +Y up in the printed image. Poses come out in Blender's camera
convention (camera looks along its -Z, +Y up) as row-major 4x4 camera_to_world matrices.

OpenCV's pixel coordinates put the centre of pixel (0, 0) at (0, 0), so the optical centre of
a W x H image is ((W-1)/2, (H-1)/2): that is the default principal point here.
"""
from __future__ import annotations

import dataclasses
import json
import os
from typing import Iterator

import numpy as np

from ..errors import PlateLightError
from . import calibration

# OpenCV camera (x right, y down, looks along +z) -> Blender camera (x right, y up, looks along -z)
# FFmpeg's own log lines would follow our one-sentence errors on stderr (read when first used).
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
CV_TO_BLENDER_CAMERA = np.diag([1.0, -1.0, -1.0])
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr", ".webp")
VIDEO_EXTENSIONS = (".mp4", ".mov", ".avi", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg")
# A marker whose side is shorter than this in the image decodes unreliably and poses badly.
MIN_MARKER_SIDE_PX = 12.0
# A marker's border ring must be this much darker (relative, linear light) than just outside it.
MIN_BORDER_CONTRAST = 0.5
_SRGB_TO_LINEAR = np.array([(v / 12.92) if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4
                            for v in np.arange(256) / 255.0], dtype=np.float32) * 255.0


def get_dictionary(name: str):
    import cv2

    key = name.strip().upper()
    if not key.startswith("DICT_"):
        key = "DICT_" + key
    if not hasattr(cv2.aruco, key):
        raise PlateLightError(
            f"Unknown marker dictionary '{name}'; use one of OpenCV's, e.g. DICT_4X4_50 or DICT_6X6_250.")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, key))


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


# ---------------------------------------------------------------------------------- targets
@dataclasses.dataclass
class MarkerTarget:
    """One square ArUco marker of side ``size`` metres (any id, or ``marker_id``)."""
    dictionary: str
    size: float
    marker_id: int | None = None

    def __post_init__(self):
        if not (np.isfinite(self.size) and self.size > 0):
            raise PlateLightError(f"The marker size must be a positive length in metres, not {self.size}.")
        self.cv_dictionary = get_dictionary(self.dictionary)

    @property
    def extent(self) -> tuple[float, float]:
        return (self.size, self.size)

    def corner_points(self) -> np.ndarray:
        """Object points of the four corners in OpenCV's order (top-left, top-right,
        bottom-right, bottom-left), in the world frame; the order SOLVEPNP_IPPE_SQUARE wants."""
        h = self.size / 2.0
        return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)


@dataclasses.dataclass
class CharucoTarget:
    """A ChArUco board: ``squares`` (columns, rows), square and marker side in metres."""
    dictionary: str
    squares: tuple[int, int]
    square_size: float
    marker_size: float
    legacy: bool = False

    def __post_init__(self):
        import cv2

        if min(self.squares) < 2:
            raise PlateLightError("A ChArUco board needs at least 2 x 2 squares.")
        if not (0 < self.marker_size < self.square_size):
            raise PlateLightError("The ChArUco marker size must be positive and smaller than the square size.")
        self.cv_dictionary = get_dictionary(self.dictionary)
        self.board = cv2.aruco.CharucoBoard(tuple(int(v) for v in self.squares), float(self.square_size),
                                            float(self.marker_size), self.cv_dictionary)
        self.board.setLegacyPattern(bool(self.legacy))

    @property
    def size(self) -> float:
        return self.square_size

    @property
    def extent(self) -> tuple[float, float]:
        return (self.squares[0] * self.square_size, self.squares[1] * self.square_size)

    def board_to_world(self, points: np.ndarray) -> np.ndarray:
        """OpenCV's board frame (origin top-left, y down, z into the board) -> ours."""
        w, h = self.extent
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.stack([p[:, 0] - w / 2, h / 2 - p[:, 1], -p[:, 2]], axis=1)


# -------------------------------------------------------------------------------- detection
@dataclasses.dataclass
class Detection:
    object_points: np.ndarray | None = None   # (N, 3) world frame
    image_points: np.ndarray | None = None    # (N, 2) pixels
    kind: str = "none"                        # "marker", "charuco" or "none"
    rejected: int = 0                         # square candidates that did not decode
    too_small: bool = False
    side_px: float = 0.0


def _detector_parameters():
    import cv2

    params = cv2.aruco.DetectorParameters()
    # Sub-pixel corners: the pose accuracy the issue asks for (0.1 deg) needs them.
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 4
    params.cornerRefinementMinAccuracy = 0.01
    params.cornerRefinementMaxIterations = 50
    return params


def _nested_detector_parameters():
    """Second pass: keep nested candidates. With a paper margin narrower than one bit, the
    paper's edge decodes as the marker too (error correction) and wins over the real border."""
    params = _detector_parameters()
    params.minMarkerDistanceRate = 0.0
    params.minGroupDistance = 0.0
    return params


def to_gray8(image: np.ndarray) -> np.ndarray:
    import cv2

    img = np.asarray(image)
    if img.dtype != np.uint8:
        if np.issubdtype(img.dtype, np.floating):
            img = np.clip(np.nan_to_num(img), 0, 1) ** (1 / 2.2) * 255 + 0.5
        else:
            img = img.astype(np.float64) * (255.0 / np.iinfo(img.dtype).max) + 0.5
        img = img.astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2GRAY)
    return img


class Tracker:
    """Detects the target in frames and solves the camera pose."""

    def __init__(self, target, intrinsics: Intrinsics | None = None):
        import cv2

        self.target = target
        self.intrinsics = intrinsics
        self.detector = cv2.aruco.ArucoDetector(target.cv_dictionary, _detector_parameters())
        self.nested_detector = cv2.aruco.ArucoDetector(target.cv_dictionary, _nested_detector_parameters())
        if isinstance(target, CharucoTarget):
            cparams = cv2.aruco.CharucoParameters()
            self.charuco = cv2.aruco.CharucoDetector(target.board, cparams, _detector_parameters())

    def detect(self, image: np.ndarray) -> Detection:
        import cv2

        gray = to_gray8(image)
        if isinstance(self.target, CharucoTarget):
            ch_corners, ch_ids, m_corners, m_ids = self.charuco.detectBoard(gray)
            if m_ids is None or ch_ids is None or len(ch_ids) < 4:
                _, _, rejected = self.detector.detectMarkers(gray)
                return Detection(rejected=len(rejected))
            side = float(np.median([_side_px(c) for c in m_corners]))
            if side < MIN_MARKER_SIDE_PX:
                return Detection(too_small=True, side_px=side)
            # OpenCV before its 2026 fix returns ChArUco corners +0.5 px off (measured on Cycles
            # renders); the chessboard saddles themselves refine to ~0.1 px with a small window.
            # With the fix its corners are used as they are (refining again moved them up to
            # 0.5 px on real JPEG photos: calibration RMS 0.19 -> 0.25 px).
            if calibration.charuco_corners_biased():
                win = int(np.clip(round(side / 7), 2, 6))
                ch_corners = cv2.cornerSubPix(gray, ch_corners.astype(np.float32), (win, win), (-1, -1),
                                              (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-3))
            obj, img = self.target.board.matchImagePoints(ch_corners, ch_ids)
            return Detection(self.target.board_to_world(obj), img.reshape(-1, 2).astype(np.float64),
                             "charuco", side_px=side)
        det = Detection()
        for detector in (self.detector, self.nested_detector):
            corners, ids, rejected = detector.detectMarkers(gray)
            if ids is None or len(ids) == 0:
                return Detection(rejected=len(rejected))
            det = self._best_marker(gray, corners, ids, rejected)
            if det.kind != "none" or det.too_small:
                return det
        return det

    def _best_marker(self, gray, corners, ids, rejected) -> Detection:
        ids = ids.reshape(-1)
        wanted = ids if self.target.marker_id is None else ids[ids == self.target.marker_id]
        if len(wanted) == 0:
            return Detection(rejected=len(rejected))
        cells = self.target.cv_dictionary.markerSize + 2
        # The quad whose outer ring is black inside and bright outside is the marker's border,
        # not the paper's edge or the inner edge of the border; several markers: the largest
        # one is the target.
        best, best_key, small = None, None, 0.0
        for quad, marker in zip(corners, ids):
            if marker not in wanted:
                continue
            if _side_px(quad) < MIN_MARKER_SIDE_PX:
                small = max(small, _side_px(quad))
                continue
            refined = refine_quad_edges(gray, quad)
            contrast = border_contrast(gray, refined, cells)
            if contrast < MIN_BORDER_CONTRAST:
                # Often the inner edge of the black border (JPEG-compressed frames): grow it
                # by one bit on every side and look again.
                refined = refine_quad_edges(gray, grow_quad(refined, 1.0 / (cells - 2)))
                contrast = border_contrast(gray, refined, cells)
            if contrast < MIN_BORDER_CONTRAST:
                continue
            if best_key is None or _side_px(refined) > best_key:
                best, best_key = refined, _side_px(refined)
        if best is None:
            if small:
                return Detection(too_small=True, side_px=small)
            return Detection(rejected=len(rejected) + len(corners))
        return Detection(self.target.corner_points(), best, "marker", side_px=best_key)

    def solve(self, det: Detection):
        """(rvec, tvec, rms reprojection px) of the world in OpenCV camera coordinates."""
        import cv2

        k, dist = self.intrinsics.matrix(), self.intrinsics.dist_array()
        obj = det.object_points.astype(np.float64)
        img = det.image_points.astype(np.float64)
        if det.kind == "marker":
            ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        else:
            ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE)
            if ok:
                rvec, tvec = cv2.solvePnPRefineLM(obj, img, k, dist, rvec, tvec)
        if not ok:
            return None
        proj, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
        rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
        return rvec.reshape(3), tvec.reshape(3), rms


def _side_px(corners) -> float:
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    return float(np.mean(np.linalg.norm(c - np.roll(c, 1, axis=0), axis=1)))


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


# --------------------------------------------------------------------------------- frames
def list_frames(source: str | os.PathLike) -> tuple[str, list[str]]:
    """("folder", sorted image paths) or ("video", [path])."""
    source = os.fspath(source)
    if not os.path.exists(source):
        raise PlateLightError(f"Frames not found: {source}")
    if os.path.isdir(source):
        files = sorted(os.path.join(source, f) for f in os.listdir(source)
                       if f.lower().endswith(IMAGE_EXTENSIONS) and not f.startswith("."))
        if not files:
            raise PlateLightError(f"The folder holds no images ({', '.join(IMAGE_EXTENSIONS)}): {source}")
        return "folder", files
    return "video", [source]


def read_image(path: str) -> np.ndarray:
    import cv2

    img = cv2.imread(path, cv2.IMREAD_UNCHANGED) if not path.lower().endswith(".exr") else None
    if img is None and path.lower().endswith(".exr"):
        from ..exr_io import read_exr
        img = read_exr(path)[..., ::-1]
    if img is None:
        raise PlateLightError(f"Cannot read the image (not an image file, or damaged): {path}")
    return img


def iter_frames(source: str | os.PathLike) -> Iterator[tuple[int, np.ndarray]]:
    """(frame number from 1, image) for an image folder (sorted by name) or a video file."""
    import cv2

    kind, files = list_frames(source)
    if kind == "folder":
        for i, path in enumerate(files, start=1):
            yield i, read_image(path)
        return
    cap = cv2.VideoCapture(files[0])
    if not cap.isOpened():
        cap.release()
        raise PlateLightError(f"Cannot read the video (not a video file, or no codec for it): {files[0]}")
    try:
        i = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            i += 1
            yield i, img
    finally:
        cap.release()
    if i == 0:
        raise PlateLightError(f"The video holds no readable frames: {files[0]}")


# ------------------------------------------------------------------------------ smoothing
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


# --------------------------------------------------------------------------------- tracking
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
        raise PlateLightError("Give the camera: a focal length (--focal-px or --focal-mm) or a calibration file.")
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
                f"No {target.dictionary} marker was found, but {other} markers were: wrong --dictionary?")
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
        warnings.append("the poses use the calibrated lens distortion, which a Blender camera cannot "
                        "represent: undistort the plate (e.g. a Movie Distortion node) before compositing")

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


def calibrate_from_detections(detections: list[Detection], size: tuple[int, int]):
    """Intrinsics with OpenCV's five distortion coefficients from ChArUco detections:
    (Intrinsics, calibration.Calibration) (see calibration.py)."""
    usable = [d for d in detections if d.kind == "charuco" and len(d.object_points) >= 6]
    cal = calibration.calibrate([d.object_points for d in usable], [d.image_points for d in usable], size)
    return Intrinsics(cal.fx, cal.fy, cal.cx, cal.cy, cal.dist), cal


def rotation_error_deg(r_a: np.ndarray, r_b: np.ndarray) -> float:
    """Angle of the rotation taking r_b to r_a, in degrees."""
    c = (np.trace(np.asarray(r_a)[:3, :3].T @ np.asarray(r_b)[:3, :3]) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def refine_quad_edges(gray: np.ndarray, quad: np.ndarray, reach_px: float = 3.0) -> np.ndarray:
    """Refine a marker's four corners by fitting straight lines to its outer black/white edges.

    An L-shaped corner has no saddle for cornerSubPix to lock onto (measured on Cycles renders:
    0.5-0.6 px corner error); the edges do: along each side, the sub-pixel crossing of the
    mid-level between the black border and the white quiet zone is found on many normals, a line
    is fitted to them and neighbouring lines are intersected. Corners are (4, 2), clockwise in
    the image from top-left (OpenCV's order); returns the input when a side cannot be fitted."""
    import cv2

    # The mid-level of a blurred step is only at the true edge in linear light: 8-bit frames are
    # sRGB-encoded, and thresholding them there shrinks the black border by ~0.3 px.
    img = _SRGB_TO_LINEAR[np.asarray(gray, dtype=np.uint8)]
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    side = _side_px(q)
    reach = float(min(reach_px, max(1.0, side / 8.0)))
    offsets = np.arange(-reach, reach + 1e-9, 0.25)
    lines = []
    for i in range(4):
        a, b = q[i], q[(i + 1) % 4]
        e = b - a
        length = np.linalg.norm(e)
        e /= length
        n = np.array([e[1], -e[0]])                    # outward for a clockwise quad (y down)
        s = np.linspace(0.12, 0.88, max(8, int(length / 2)))
        base = a[None, :] + s[:, None] * (b - a)[None, :]
        pts = base[:, None, :] + offsets[None, :, None] * n[None, None, :]
        prof = cv2.remap(img, pts[..., 0].astype(np.float32), pts[..., 1].astype(np.float32),
                         cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        lo, hi = prof[:, :3].mean(axis=1), prof[:, -3:].mean(axis=1)
        mid = 0.5 * (lo + hi)[:, None]
        cross = (prof[:, :-1] < mid) & (prof[:, 1:] >= mid)
        # ringing can cross twice: the crossing nearest the current edge wins
        k = np.argmin(np.where(cross, np.abs(offsets[:-1])[None, :], np.inf), axis=1)
        ok = (hi - lo >= 20) & cross.any(axis=1)       # a clear dark-inside / bright-outside step
        rows = np.arange(len(s))
        p0, p1 = prof[rows, k], prof[rows, k + 1]
        t = offsets[k] + (mid[:, 0] - p0) / np.where(p1 != p0, p1 - p0, 1.0) * (offsets[1] - offsets[0])
        found = (base + t[:, None] * n[None, :])[ok]
        if len(found) < 4:
            return q
        centre = found.mean(0)
        _, _, vt = np.linalg.svd(found - centre, full_matrices=False)
        lines.append((centre, vt[0]))
    out = np.empty((4, 2))
    for i in range(4):
        (p1, d1), (p2, d2) = lines[i - 1], lines[i]
        m = np.array([d1, -d2]).T
        if abs(np.linalg.det(m)) < 1e-9:
            return q
        t = np.linalg.solve(m, p2 - p1)
        out[i] = p1 + t[0] * d1
    if np.max(np.linalg.norm(out - q, axis=1)) > reach:   # a fit that jumped away is not trusted
        return q
    return out


def border_contrast(gray: np.ndarray, quad: np.ndarray, cells: int) -> float:
    """Relative linear-light contrast between a thin ring just outside ``quad`` and the rings of
    the marker's black border cells inside it (1 = black inside, <= 0 = not darker)."""
    import cv2

    lin = _SRGB_TO_LINEAR[np.asarray(gray, dtype=np.uint8)] / 255.0
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
    hom = cv2.getPerspectiveTransform(square, np.asarray(quad, dtype=np.float32).reshape(4, 2))
    t = np.linspace(0.1, 0.9, 24)
    cell = 1.0 / cells

    def ring(depth):
        lo, hi = depth, 1 - depth
        pts = np.concatenate([np.stack([t, np.full_like(t, lo)], 1), np.stack([t, np.full_like(t, hi)], 1),
                              np.stack([np.full_like(t, lo), t], 1), np.stack([np.full_like(t, hi), t], 1)])
        img_pts = cv2.perspectiveTransform(pts.reshape(-1, 1, 2).astype(np.float32), hom).reshape(-1, 2)
        vals = cv2.remap(lin, img_pts[:, 0].reshape(1, -1), img_pts[:, 1].reshape(1, -1), cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)
        return float(np.mean(vals))

    # Both just inside the edge and mid-cell must be black: the paper's edge around a margin
    # narrower than a bit has black mid-cell but white just inside.
    outside = ring(-0.2 * cell)
    inside = max(ring(0.15 * cell), ring(0.5 * cell))
    return (outside - inside) / max(outside, 1e-3)      # relative: dim exposures count alike


def grow_quad(quad: np.ndarray, fraction: float) -> np.ndarray:
    """The quad extended by ``fraction`` of its size on every side, in perspective."""
    import cv2

    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
    hom = cv2.getPerspectiveTransform(square, np.asarray(quad, dtype=np.float32).reshape(4, 2))
    grown = np.array([[-fraction, -fraction], [1 + fraction, -fraction], [1 + fraction, 1 + fraction],
                      [-fraction, 1 + fraction]], dtype=np.float32)
    return cv2.perspectiveTransform(grown.reshape(-1, 1, 2), hom).reshape(4, 2).astype(np.float64)
