"""Lens distortion engine (no Blender): OpenCV's model both ways, the overscan frame, the ST-map,
and straight edges in real photos after undistortion."""
import subprocess

import numpy as np
import pytest

import support
from platelight.addon.capture.intrinsics import load_calibration
from platelight.addon.compositing import lens
from platelight.addon.errors import PlateLightError


def _real_data():
    """/…/shared/data/real next to the main checkout (worktrees live elsewhere)."""
    common = subprocess.run(["git", "-C", str(support.REPO), "rev-parse", "--git-common-dir"],
                            capture_output=True, text=True).stdout.strip()
    candidates = [support.SHARED]
    if common:
        candidates.append((support.REPO / common).resolve().parent.parent / "shared")
    for shared in candidates:
        if (shared / "data" / "real").is_dir():
            return shared / "data" / "real"
    pytest.skip("the shared real-photo data is not here")


REAL = None


@pytest.fixture(scope="module")
def calib():
    global REAL
    REAL = _real_data()
    folder = REAL / "charuco_calibration"
    return folder, load_calibration(folder / "tutorial_camera_charuco.yml")


STRONG = (-0.32, 0.11, 0.0015, -0.002, -0.01)   # a wide-angle barrel lens


def test_model_matches_opencv_both_ways():
    import cv2

    rng = np.random.default_rng(3)
    pts = rng.uniform(-0.7, 0.7, (2000, 2))
    for dist in (STRONG, (0.12, -1.08, 1e-4, -5e-4, 2.95), (0.2, 0.05, -0.01, 0.01, 0.0)):
        xd, yd = lens.distort_normalized(pts[:, 0], pts[:, 1], dist)
        ref, _ = cv2.projectPoints(np.c_[pts, np.ones(len(pts))], np.zeros(3), np.zeros(3), np.eye(3),
                                   np.array(dist))
        assert np.abs(np.c_[xd, yd] - ref.reshape(-1, 2)).max() < 1e-12
        xu, yu = lens.undistort_normalized(xd, yd, dist)
        assert np.abs(np.c_[xu, yu] - pts).max() < 1e-10


def test_render_frame_covers_the_distorted_plate_and_is_identity_without_distortion():
    fx, fy, cx, cy, w, h = 300.0, 300.0, 161.2, 118.7, 320, 240
    plain = lens.render_frame(fx, fy, cx, cy, (0,) * 5, w, h)
    assert plain.scale == 1.0
    np.testing.assert_allclose(plain.ideal_to_render(np.array([0.0, 319.0]), np.array([0.0, 239.0])),
                               [[0, 319], [0, 239]], atol=1e-9)
    frame = lens.render_frame(fx, fy, cx, cy, STRONG, w, h)
    assert 0.7 < frame.scale < 0.99
    uv = lens.st_map(fx, fy, cx, cy, STRONG, w, h, frame)
    assert uv[..., :2].min() > 0 and uv[..., :2].max() < 1     # every plate pixel is rendered
    assert uv[..., :2].min() < 0.02                              # and little is wasted


def test_folding_calibration_is_refused():
    with pytest.raises(PlateLightError, match="folds back inside the frame"):
        lens.render_frame(300, 300, 160, 120, (0.0, -2.0, 0, 0, 0), 320, 240)
    with pytest.raises(PlateLightError, match="rational or thin-prism"):
        lens.render_frame(300, 300, 160, 120, (0.1, 0, 0, 0, 0, 0.2, 0, 0), 320, 240)


def _board_rows(image):
    """RMS distance of ChArUco corners from the best line through each row and column (px)."""
    import cv2

    board = cv2.aruco.CharucoBoard((5, 7), 0.04, 0.02, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(image)
    assert ids is not None and len(ids) >= 12
    corners, ids = corners.reshape(-1, 2), ids.ravel()
    out = []
    for key in (ids // 4, ids % 4):        # 4 inner corners a row on a 5 x 7 board
        for k in np.unique(key):
            p = corners[key == k]
            if len(p) >= 3:
                c = p - p.mean(0)
                normal = np.linalg.svd(c)[2][1]
                out.append(np.sqrt(np.mean((c @ normal) ** 2)))
    return np.array(out)


def test_real_board_edges_are_straight_after_undistortion(calib):
    """OpenCV's calibration of these four webcam photos, applied by our undistortion: every row
    and column of board corners is straight to < 0.3 px RMS (the detector's own noise)."""
    import cv2

    folder, k = calib
    frame = lens.render_frame(k.fx, k.fy, k.cx, k.cy, k.dist, 640, 480)
    for path in sorted(folder.glob("img_*.jpg")):
        image = cv2.imread(str(path))
        straight = lens.undistort_to_render(image, k.fx, k.fy, k.cx, k.cy, k.dist, frame)
        assert _board_rows(straight).max() < 0.3, path.name


def test_real_photo_through_a_strong_lens_comes_back_straight(calib):
    """The same real photos seen through a strong barrel lens (applied with OpenCV's own
    undistortion maps, inverted): the board's rows bend by pixels; our undistortion of that
    picture makes them straight again, and agrees with cv2.undistort."""
    import cv2

    folder, k = calib
    fx, fy, cx, cy = 420.0, 420.0, 322.0, 236.0
    kmat = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
    frame = lens.render_frame(fx, fy, cx, cy, STRONG, 640, 480)
    for path in sorted(folder.glob("img_*.jpg"))[:2]:
        photo = cv2.imread(str(path))
        # distorted[j, i] = photo at the ideal point whose distortion lands on (i, j)
        j, i = np.mgrid[0:480, 0:640].astype(np.float64)
        xu, yu = lens.undistort_normalized((i - cx) / fx, (j - cy) / fy, STRONG)
        bent = cv2.remap(photo, (fx * xu + cx).astype(np.float32), (fy * yu + cy).astype(np.float32),
                         cv2.INTER_CUBIC)
        ours = lens.undistort_to_render(bent, fx, fy, cx, cy, STRONG, frame)
        # measured: curved 0.79 / 0.97 px, straightened 0.08 / 0.19 px (the photo itself: 0.12 / 0.20)
        assert _board_rows(bent).max() > 0.6, path.name
        assert _board_rows(ours).max() < min(0.3, _board_rows(bent).max() / 2.5), path.name
        # the same undistortion as OpenCV's, in OpenCV's frame (scale 1)
        same = lens.RenderFrame(640, 480, 1.0, ((640 - 1) / 2, (480 - 1) / 2))
        mine = lens.undistort_to_render(bent, fx, fy, cx, cy, STRONG, same).astype(np.float64)
        ref = cv2.undistort(bent, kmat, np.array(STRONG)).astype(np.float64)
        inside = (mine.sum(-1) > 0) & (ref.sum(-1) > 0)
        assert np.median(np.abs(mine - ref)[inside]) <= 1.0      # 8-bit values, interpolation


def test_clip_camera_settings_swap_and_flip_the_tangential_pair():
    s = lens.clip_camera_settings(500, 500, 319.5, 239.5, (0.1, 0.02, 0.003, -0.004, 0.05), 640, 480)
    assert s["distortion_model"] == "BROWN"
    assert (s["brown_k1"], s["brown_k2"], s["brown_k3"], s["brown_k4"]) == (0.1, 0.02, 0.05, 0.0)
    assert (s["brown_p1"], s["brown_p2"]) == (-0.004, -0.003)
    assert s["principal_point_pixels"] == (320.0, 240.0)
