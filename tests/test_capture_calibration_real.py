"""Calibration and poses on OpenCV's own four real ChArUco tutorial photos (shared/data/real/
charuco_calibration, with OpenCV's calibration of them in tutorial_camera_charuco.yml)."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import real_photos as rp
import support
from platelight.addon.capture.intrinsics import load_calibration
from platelight.addon.capture.poses import blender_to_cv_pose
from platelight.addon.capture.targets import CharucoTarget
from platelight.addon.capture.tracking import track

pytestmark = pytest.mark.skipif(not rp.CHARUCO.is_dir(), reason="shared/data/real is not here")
BOARD = ("DICT_6X6_250", (5, 7), 0.04, 0.02)
SIZE = (640, 480)


@pytest.fixture(scope="module")
def calibrated():
    return track(str(rp.CHARUCO), CharucoTarget(*BOARD), calibrate=True)


def _opencv_corners():
    """OpenCV's own ChArUco corners of each photo, in its board frame: [(obj, img, ids)]."""
    board = CharucoTarget(*BOARD).board
    detector = cv2.aruco.CharucoDetector(board)
    out = []
    for path in sorted(rp.CHARUCO.glob("img_*.jpg")):
        corners, ids, _, _ = detector.detectBoard(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))
        obj, img = board.matchImagePoints(corners, ids)
        out.append((obj, img, ids.reshape(-1)))
    return out


def test_same_corners_same_intrinsics_as_opencv(calibrated):
    """cv2.calibrateCamera on OpenCV's own corners of the same photos: within 1 %."""
    views = _opencv_corners()
    _, k, _, _, _ = cv2.calibrateCamera([v[0] for v in views], [v[1] for v in views], SIZE, None, None)
    intr = calibrated.intrinsics
    for got, want in ((intr.fx, k[0, 0]), (intr.fy, k[1, 1]), (intr.cx, k[0, 2]), (intr.cy, k[1, 2])):
        assert got == pytest.approx(want, rel=0.01)


def test_intrinsics_within_3_percent_of_opencvs_calibration(calibrated):
    ref = load_calibration(rp.CHARUCO / "tutorial_camera_charuco.yml")
    intr = calibrated.intrinsics
    assert intr.fx == pytest.approx(ref.fx, rel=0.03) and intr.fy == pytest.approx(ref.fy, rel=0.03)
    assert intr.cx == pytest.approx(ref.cx, rel=0.03) and intr.cy == pytest.approx(ref.cy, rel=0.03)
    assert calibrated.calibration["rms_px"] < 0.3


def test_uncertainty_reported_and_four_views_called_weak(calibrated):
    cal = calibrated.calibration
    assert set(cal["std"]) == {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"}
    assert all(v > 0 for v in cal["std"].values())
    ref = load_calibration(rp.CHARUCO / "tutorial_camera_charuco.yml")
    # OpenCV's own result lies within the reported uncertainty
    assert abs(calibrated.intrinsics.fx - ref.fx) < 3 * cal["std"]["fx"]
    weak = [w for w in calibrated.warnings if "calibration is weak" in w]
    assert weak and "only 4 views" in weak[0] and "tilted 30-45 degrees" in weak[0]


def test_poses_reproject_onto_opencvs_corners_within_a_pixel(tmp_path):
    """Poses tracked with OpenCV's calibration put the board's corners back onto the corners
    OpenCV itself detects in the real photos."""
    ref = load_calibration(rp.CHARUCO / "tutorial_camera_charuco.yml")
    target = CharucoTarget(*BOARD)
    result = track(str(rp.CHARUCO), target, intrinsics=ref)
    assert result.tracked_count == 4
    worst = 0.0
    for entry, (obj, img, _) in zip(result.frames, _opencv_corners()):
        r, t = blender_to_cv_pose(np.array(entry["camera_to_world"]))
        rvec, _ = cv2.Rodrigues(r)
        proj, _ = cv2.projectPoints(target.board_to_world(obj), rvec, t, ref.matrix(), ref.dist_array())
        worst = max(worst, float(np.max(np.linalg.norm(proj.reshape(-1, 2) - img.reshape(-1, 2), axis=1))))
    assert worst < 1.0


def test_track_cli_calibrates_real_photos(tmp_path):
    out = tmp_path / "poses.json"
    proc = support.run_cli("track", rp.CHARUCO, "--board", "charuco", "--dictionary", "DICT_6X6_250",
                           "--squares", "5x7", "--square-size", 0.04, "--marker-size", 0.02, "--calibrate",
                           "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "calibration is weak" in proc.stderr and "Traceback" not in proc.stderr
    data = json.loads(out.read_text())
    cal = data["calibration"]
    assert [cal["distortion"][k] for k in ("k1", "k2", "p1", "p2", "k3")] == cal["dist"]
    assert data["intrinsics"]["dist"] == pytest.approx(cal["dist"])
    assert data["intrinsics"]["fx"] == pytest.approx(cal["fx"])
