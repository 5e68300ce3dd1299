"""Tracking engine (no Blender): projective ground truth made by warping the printed target
with the homography of a known pose, the OpenCV -> Blender camera convention, smoothing,
lost frames, printable boards, the track CLI and every bad input of issue 7."""
from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

import support
from platelight.addon.capture.boards import target_image, write_target
from platelight.addon.capture.detection import Tracker
from platelight.addon.capture.intrinsics import Intrinsics
from platelight.addon.capture.poses import blender_to_cv_pose, cv_pose_to_blender, rotation_error_deg
from platelight.addon.capture.smoothing import smooth_poses
from platelight.addon.capture.targets import CharucoTarget, MarkerTarget
from platelight.addon.capture.tracking import track
from platelight.addon.errors import PlateLightError

W, H, F = 640, 480, 600.0
PX_PER_M = 5000.0
MARGIN = 0.01


def look_at(position, target=(0, 0, 0), roll_deg=0.0):
    p = np.asarray(position, float)
    back = p - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    a = math.radians(roll_deg)
    roll = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = np.stack([right, up, back], axis=1) @ roll
    m[:3, 3] = p
    return m


def warp_target(texture, extent, camera_to_world, size=(W, H), f=F, ss=4, background=0.5):
    """Image of the printed target (texture covering extent + margin, centred, +Y up) seen by
    a pinhole camera: the plane's homography K [r1 r2 t] composed with texel -> plane metres.
    Supersampled 4x and area-averaged in linear light, like a camera's pixels."""
    k = np.array([[f * ss, 0, (size[0] * ss - 1) / 2], [0, f * ss, (size[1] * ss - 1) / 2], [0, 0, 1]])
    r, t = blender_to_cv_pose(camera_to_world)
    plane = k @ np.column_stack([r[:, 0], r[:, 1], t])
    th, tw = texture.shape
    half_w, half_h = extent[0] / 2 + MARGIN, extent[1] / 2 + MARGIN
    # texel centre (i + 0.5) -> metres; OpenCV's texel coordinates put centres at integers
    tex_to_plane = np.array([[2 * half_w / tw, 0, -half_w + half_w / tw],
                             [0, -2 * half_h / th, half_h - half_h / th], [0, 0, 1]])
    hom = plane @ tex_to_plane
    lin = (texture.astype(np.float32) / 255.0) ** 2.2
    big = cv2.warpPerspective(lin, hom, (size[0] * ss, size[1] * ss), flags=cv2.INTER_AREA,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=background)
    small = big.reshape(size[1], ss, size[0], ss).mean(axis=(1, 3))
    return (np.clip(small, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)


def path(n, distance):
    return [look_at((distance * math.sin(a), 0.1 * math.cos(3 * a), distance * math.cos(a)),
                    (0.01 * math.sin(2 * a), 0, 0), roll_deg=8 * math.sin(5 * a))
            for a in np.radians(np.linspace(-35, 35, n))]


@pytest.fixture(scope="module")
def marker_frames(tmp_path_factory):
    folder = tmp_path_factory.mktemp("warped_marker")
    target = MarkerTarget("DICT_4X4_50", 0.12)
    tex = target_image(target, dpi=PX_PER_M * 0.0254, margin_m=MARGIN)
    poses = path(5, 0.5)
    for i, m in enumerate(poses, start=1):
        cv2.imwrite(str(folder / f"f{i:03d}.png"), warp_target(tex, target.extent, m))
    return folder, target, poses, tex


def test_opencv_to_blender_camera_convention():
    # A camera 2 m above the marker looking straight down at it, image +Y = marker +Y:
    # OpenCV's camera has y down and looks along +z, so R = diag(1, -1, -1) and t = (0, 0, 2).
    m = cv_pose_to_blender(cv2.Rodrigues(np.diag([1.0, -1.0, -1.0]))[0], [0, 0, 2.0])
    assert np.allclose(m[:3, :3], np.eye(3), atol=1e-12)    # Blender camera: looks along -Z, +Y up
    assert np.allclose(m[:3, 3], [0, 0, 2.0])
    r, t = blender_to_cv_pose(m)
    assert np.allclose(r, np.diag([1.0, -1.0, -1.0])) and np.allclose(t, [0, 0, 2])


def test_marker_corner_order_matches_world_frame():
    """The marker's top-left corner in the printed image is at (-s/2, +s/2, 0) in the world."""
    target = MarkerTarget("DICT_4X4_50", 0.1)
    tex = target_image(target, dpi=PX_PER_M * 0.0254, margin_m=MARGIN)
    img = warp_target(tex, target.extent, look_at((0, 0, 0.4)))
    det = Tracker(target).detect(img)
    tl = det.image_points[0]
    assert tl[0] < W / 2 and tl[1] < H / 2                  # upper left of the image
    assert np.allclose(det.object_points[0], [-0.05, 0.05, 0])


def test_single_marker_ippe_pose_on_warped_frames(marker_frames):
    folder, target, poses, _ = marker_frames
    result = track(folder, target, focal_px=F)
    rot = [rotation_error_deg(np.array(f["camera_to_world"]), p) for f, p in zip(result.frames, poses)]
    pos = [1000 * np.linalg.norm(np.array(f["camera_to_world"])[:3, 3] - p[:3, 3])
           for f, p in zip(result.frames, poses)]
    assert np.mean(rot) < 0.1 and np.mean(pos) < 1.0
    assert max(f["reprojection_px"] for f in result.frames) < 0.5


def test_charuco_board_and_printable_image_roundtrip(tmp_path):
    target = CharucoTarget("DICT_5X5_100", (6, 8), 0.03, 0.022)
    tex = target_image(target, dpi=PX_PER_M * 0.0254, margin_m=MARGIN)
    assert tex.shape == (round((0.24 + 0.02) * PX_PER_M), round((0.18 + 0.02) * PX_PER_M))
    truth = look_at((0.15, -0.1, 0.45), roll_deg=-12)
    img = warp_target(tex, target.extent, truth)
    tracker = Tracker(target, Intrinsics.from_focal_px(F, W, H))
    det = tracker.detect(img)
    assert det.kind == "charuco" and len(det.object_points) >= 30
    rvec, tvec, rms = tracker.solve(det)
    m = cv_pose_to_blender(rvec, tvec)
    assert rotation_error_deg(m, truth) < 0.1
    assert np.linalg.norm(m[:3, 3] - truth[:3, 3]) < 1e-3
    assert rms < 0.3


def test_printable_pdf_has_true_size(tmp_path):
    target = MarkerTarget("DICT_4X4_50", 0.1)
    pdf = tmp_path / "marker.pdf"
    gray = write_target(pdf, target, dpi=300, margin_m=0.01)
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF-1.4") and data.rstrip().endswith(b"%%EOF")
    media = data.split(b"/MediaBox [")[1].split(b"]")[0].split()
    width_pt = float(media[2])
    assert width_pt / 72 * 25.4 == pytest.approx(120.0, abs=0.1)   # 100 mm marker + 2 x 10 mm margin
    assert gray.shape[0] == gray.shape[1]
    png = tmp_path / "marker.png"
    write_target(png, target, dpi=300)
    assert cv2.imread(str(png), 0).shape == gray.shape


def test_smoothing_reduces_jitter_and_keeps_a_still_camera_still():
    rng = np.random.default_rng(3)
    frames = list(range(1, 41))
    truth = [look_at((0.3 + 0.005 * f, 0.05, 0.5)) for f in frames]
    noisy = []
    for m in truth:
        n = m.copy()
        axis = rng.normal(size=3)
        r, _ = cv2.Rodrigues(axis / np.linalg.norm(axis) * math.radians(0.3))
        n[:3, :3] = r @ m[:3, :3]
        n[:3, 3] += rng.normal(scale=0.002, size=3)
        noisy.append(n)
    smooth = smooth_poses(frames, noisy, sigma=3.0)
    inner = slice(5, -5)
    err = lambda ms: np.mean([rotation_error_deg(a, b) for a, b in zip(ms[inner], truth[inner])])
    perr = lambda ms: np.mean([np.linalg.norm(a[:3, 3] - b[:3, 3]) for a, b in zip(ms[inner], truth[inner])])
    assert err(smooth) < 0.5 * err(noisy)
    assert perr(smooth) < 0.5 * perr(noisy)
    still = smooth_poses(frames, [truth[0]] * len(frames), sigma=3.0)
    assert all(np.allclose(m, truth[0]) for m in still)
    assert smooth_poses(frames, noisy, sigma=0) [3].tolist() == noisy[3].tolist()


def _frames_with_gap(folder, marker_frames):
    src, target, poses, tex = marker_frames
    blank = np.full((H, W), 128, np.uint8)
    for i, name in enumerate(sorted(p.name for p in src.iterdir()), start=1):
        img = cv2.imread(str(src / name), 0)
        cv2.imwrite(str(folder / name), blank if i in (2, 3) else img)
    return target, poses


@pytest.mark.parametrize("lost", ["interpolate", "skip"])
def test_lost_frames_reported_and_interpolated_or_left_unkeyed(tmp_path, marker_frames, lost):
    target, poses = _frames_with_gap(tmp_path, marker_frames)
    result = track(tmp_path, target, focal_px=F, lost=lost)
    assert [f["tracked"] for f in result.frames] == [True, False, False, True, True]
    assert any("lost in 2 of 5 frames: 2-3" in w for w in result.warnings)
    if lost == "skip":
        assert result.frames[1]["camera_to_world"] is None
    else:
        m1, m4 = (np.array(result.frames[i]["camera_to_world"]) for i in (0, 3))
        m2 = np.array(result.frames[1]["camera_to_world"])
        assert result.frames[1]["interpolated"] is True
        # one third of the way: positions linear, rotation on the geodesic
        assert np.allclose(m2[:3, 3], m1[:3, 3] + (m4[:3, 3] - m1[:3, 3]) / 3, atol=1e-9)
        total = rotation_error_deg(m1, m4)
        assert rotation_error_deg(m1, m2) == pytest.approx(total / 3, abs=1e-6)


def test_video_file_input(tmp_path, marker_frames):
    src, target, poses, _ = marker_frames
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 25, (W, H))
    assert writer.isOpened()
    for name in sorted(p.name for p in src.iterdir()):
        writer.write(cv2.cvtColor(cv2.imread(str(src / name), 0), cv2.COLOR_GRAY2BGR))
    writer.release()
    result = track(video, target, focal_px=F)
    assert [f["frame"] for f in result.frames] == [1, 2, 3, 4, 5]
    rot = [rotation_error_deg(np.array(f["camera_to_world"]), p) for f, p in zip(result.frames, poses)]
    assert np.mean(rot) < 0.3                               # JPEG-compressed frames


def test_track_cli_contract(tmp_path, marker_frames):
    folder, target, poses, _ = marker_frames
    out = tmp_path / "poses.json"
    proc = support.run_cli("track", folder, "--dictionary", "DICT_4X4_50", "--marker-size", 0.12,
                           "--focal-px", F, "--out", out)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert set(data) >= {"image_size", "intrinsics", "frames"}
    assert set(data["intrinsics"]) >= {"fx", "fy", "cx", "cy"}
    frame = data["frames"][0]
    assert set(frame) >= {"frame", "tracked", "camera_to_world", "reprojection_px"}
    assert rotation_error_deg(np.array(frame["camera_to_world"]), poses[0]) < 0.2
    calib = tmp_path / "calib.json"
    calib.write_text(json.dumps({"intrinsics": data["intrinsics"]}))
    proc = support.run_cli("track", folder, "--marker-size", 0.12, "--calibration", calib, "--out", out)
    assert proc.returncode == 0, proc.stderr
    board = tmp_path / "board.pdf"
    proc = support.run_cli("track", "--board", "charuco", "--squares", "5x7", "--square-size", 0.04,
                           "--marker-size", 0.03, "--print-board", board)
    assert proc.returncode == 0 and board.read_bytes().startswith(b"%PDF")


# ------------------------------------------------------------------------------ bad input
def _cli_error(*args):
    proc = support.run_cli("track", *args)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


def test_no_marker_in_any_frame(tmp_path):
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i}.png"), np.full((120, 160), 200, np.uint8))
    msg = _cli_error(tmp_path, "--marker-size", 0.1, "--focal-px", 100, "--out", tmp_path / "p.json")
    assert "No DICT_4X4_50 marker was found in any of the 3 frames" in msg
    assert not (tmp_path / "p.json").exists()


def test_wrong_dictionary(tmp_path, marker_frames):
    folder = marker_frames[0]
    msg = _cli_error(folder, "--dictionary", "DICT_6X6_250", "--marker-size", 0.12, "--focal-px", F,
                     "--out", tmp_path / "p.json")
    assert "No DICT_6X6_250 marker was found, but DICT_4X4_50 markers were: wrong --dictionary?" in msg


def test_marker_too_small(tmp_path):
    target = MarkerTarget("DICT_4X4_50", 0.1)
    tex = target_image(target, dpi=PX_PER_M * 0.0254, margin_m=MARGIN)
    img = warp_target(tex, target.extent, look_at((0, 0, 6.0)))      # ~10 px a side
    cv2.imwrite(str(tmp_path / "far.png"), img)
    msg = _cli_error(tmp_path, "--marker-size", 0.1, "--focal-px", F, "--out", tmp_path / "p.json")
    assert "too small" in msg


def test_marker_blurred(tmp_path, marker_frames):
    src = marker_frames[0]
    img = cv2.imread(str(sorted(src.iterdir())[0]), 0)
    cv2.imwrite(str(tmp_path / "blur.png"), cv2.GaussianBlur(img, (0, 0), 9))
    msg = _cli_error(tmp_path, "--marker-size", 0.12, "--focal-px", F, "--out", tmp_path / "p.json")
    assert msg.endswith("Marker-like squares were seen but none could be decoded in any frame: the marker "
                        "is too small, blurred or out of focus (or the dictionary is wrong).")


def test_unreadable_frames_and_missing_inputs(tmp_path):
    (tmp_path / "0001.png").write_text("not an image")
    msg = _cli_error(tmp_path, "--marker-size", 0.1, "--focal-px", 100, "--out", tmp_path / "p.json")
    assert msg.endswith("Cannot read the image (not an image file, or damaged): " + str(tmp_path / "0001.png"))
    assert "Frames not found" in _cli_error(tmp_path / "nope", "--marker-size", 0.1, "--focal-px", 100,
                                            "--out", tmp_path / "p.json")
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"\x00" * 100)
    assert "Cannot read the video" in _cli_error(video, "--marker-size", 0.1, "--focal-px", 100,
                                                 "--out", tmp_path / "p.json")
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "holds no images" in _cli_error(empty, "--marker-size", 0.1, "--focal-px", 100,
                                           "--out", tmp_path / "p.json")


def test_bad_options(tmp_path, marker_frames):
    folder = marker_frames[0]
    out = tmp_path / "p.json"
    assert "Unknown marker dictionary 'DICT_9X9'" in _cli_error(folder, "--dictionary", "DICT_9X9",
                                                                "--marker-size", 0.1, "--focal-px", 100, "--out", out)
    assert "--marker-size" in _cli_error(folder, "--focal-px", 100, "--out", out)
    assert "focal length" in _cli_error(folder, "--marker-size", 0.1, "--out", out)
    assert "positive" in _cli_error(folder, "--marker-size", -1, "--focal-px", 100, "--out", out)
    assert "ChArUco" in _cli_error(folder, "--marker-size", 0.1, "--calibrate", "--out", out)
    assert "Calibration file not found" in _cli_error(folder, "--marker-size", 0.1, "--calibration",
                                                      tmp_path / "none.json", "--out", out)
    with pytest.raises(PlateLightError, match="Lost-frame handling"):
        track(folder, MarkerTarget("DICT_4X4_50", 0.1), focal_px=100, lost="guess")


def test_frames_of_different_sizes(tmp_path):
    cv2.imwrite(str(tmp_path / "1.png"), np.zeros((100, 120), np.uint8))
    cv2.imwrite(str(tmp_path / "2.png"), np.zeros((90, 120), np.uint8))
    msg = _cli_error(tmp_path, "--marker-size", 0.1, "--focal-px", 100, "--out", tmp_path / "p.json")
    assert "Frame 2 is 120x90 but the first frame is 120x100" in msg
