"""Finding the target in one frame and solving the camera pose from it (OpenCV ArUco/ChArUco,
bpy-free): sub-pixel corners, the marker's border told from the paper's edge, and the outer
edges of a marker refined by line fits (an L-shaped corner has no saddle to refine)."""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..imaging import SRGB8_TO_LINEAR
from .intrinsics import Intrinsics
from .targets import CharucoTarget

# A marker whose side is shorter than this in the image decodes unreliably and poses badly.
MIN_MARKER_SIDE_PX = 12.0
# A marker's border ring must be this much darker (relative, linear light) than just outside it.
MIN_BORDER_CONTRAST = 0.5

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
            if charuco_corners_biased():
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
    img = SRGB8_TO_LINEAR[np.asarray(gray, dtype=np.uint8)]
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

    lin = SRGB8_TO_LINEAR[np.asarray(gray, dtype=np.uint8)] / 255.0
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


@functools.lru_cache(maxsize=1)
def charuco_corners_biased() -> bool:
    """Whether this OpenCV's CharucoDetector returns its corners +0.5 px off (opencv #25539,
    fixed by PR #28380 in 2026, after 4.11): measured once on a generated board, whose inner
    corners lie exactly on pixel boundaries, rather than guessed from the version number."""
    import cv2

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    board = cv2.aruco.CharucoBoard((5, 7), 1.0, 0.7, dictionary)
    square, margin = 40, 20
    image = board.generateImage((5 * square + 2 * margin, 7 * square + 2 * margin), marginSize=margin, borderBits=1)
    image = cv2.GaussianBlur(image, (0, 0), 1.0)
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(image)
    if ids is None or len(ids) < 4:
        return False
    expected = margin + board.getChessboardCorners()[ids.reshape(-1)][:, :2] * square - 0.5
    return bool(np.mean(corners.reshape(-1, 2) - expected) > 0.25)
