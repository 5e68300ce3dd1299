"""Probe capture engine (no Blender): EXIF exposure times, Debevec merge against a known
radiance and tone curve, clipped-in-every-bracket detection and the grey-card repair (analytic),
mirror-ball unwrap against an independent forward model, ball finding, the probe CLI and every
bad input of issue 7."""
from __future__ import annotations

import json
import struct

import cv2
import numpy as np
import pytest

import support
from platelight.addon.capture import hdr_merge, mirror_ball
from platelight.addon.errors import PlateLightError
from platelight.addon.ibl import sh
from platelight.addon.exr_io import read_exr
from platelight.addon.ibl.equirect import (dir_to_uv, downsample_area, sample_bilinear, texel_directions,
                                           texel_solid_angles)

TIMES = [1 / 500, 1 / 125, 1 / 30, 1 / 8]


def tone(x):
    return np.clip(x, 0, 1) ** (1 / 2.2)


def brackets(radiance, times, scale=1.0):
    return [np.round(tone(radiance * t * scale) * 255).astype(np.uint8)[..., ::-1].copy() for t in times]


def smooth_env(height=64):
    """An analytic environment: a bright warm sky above, a dim bluish ground, a sharp window."""
    d = texel_directions(height, 2 * height)
    sky = 0.6 + 0.5 * np.clip(d[..., 2], 0, 1)
    env = np.stack([sky * 1.0, sky * 0.9, sky * 0.7 + 0.1 * (d[..., 0] > 0)], -1)
    env[d[..., 2] < 0] *= np.array([0.25, 0.3, 0.4])
    window = (np.abs(d[..., 1]) < 0.3) & (np.abs(d[..., 2] - 0.2) < 0.2) & (d[..., 0] > 0.8)
    env[window] = (6.0, 6.0, 5.5)
    return env.astype(np.float32)


def forward_ball(env, size, radius, camera_rotation, background=0.2, reflectance=1.0, ss=4):
    """Independent forward model: trace each (supersampled) pixel of an orthographic photo of a
    mirror ball: normal from the disc position, reflect the view ray, look the env up."""
    n = size * ss
    c = (size - 1) / 2
    ys, xs = np.mgrid[0:n, 0:n]
    px = (xs + 0.5) / ss - 0.5
    py = (ys + 0.5) / ss - 0.5
    x = (px - c) / radius
    y = -(py - c) / radius
    inside = x * x + y * y < 1
    z = np.sqrt(np.clip(1 - x * x - y * y, 0, 1))
    normal = np.stack([x, y, z], -1)
    view = np.array([0.0, 0.0, -1.0])
    refl = view - 2 * (normal @ view)[..., None] * normal
    world = refl @ np.asarray(camera_rotation).T
    u, v = dir_to_uv(world)
    img = sample_bilinear(env, u, v) * reflectance
    img[~inside] = background
    return img.reshape(size, ss, size, ss, 3).mean(axis=(1, 3)).astype(np.float32)


# ---------------------------------------------------------------------------------- EXIF
def _exif_jpeg(path, exposure, endian="<"):
    """A JPEG with an Exif block: IFD0 -> Exif IFD -> ExposureTime (RATIONAL)."""
    ok, jpg = cv2.imencode(".jpg", np.full((8, 8, 3), 128, np.uint8))
    path.write_bytes(jpg.tobytes())
    _add_exif(path, exposure, endian)


def _add_exif(path, exposure, endian="<"):
    """Insert an Exif block with ExposureTime into the JPEG at ``path``."""
    num, den = exposure
    head = (b"II*\x00" if endian == "<" else b"MM\x00*") + struct.pack(endian + "I", 8)
    ifd0 = struct.pack(endian + "H", 1) + struct.pack(endian + "HHII", 0x8769, 4, 1, 26) + struct.pack(endian + "I", 0)
    exif_ifd = (struct.pack(endian + "H", 1) + struct.pack(endian + "HHII", 0x829A, 5, 1, 44)
                + struct.pack(endian + "I", 0) + struct.pack(endian + "II", num, den))
    tiff = head + ifd0 + exif_ifd
    app1 = b"Exif\x00\x00" + tiff
    data = path.read_bytes()
    path.write_bytes(data[:2] + b"\xff\xe1" + struct.pack(">H", len(app1) + 2) + app1 + data[2:])


@pytest.mark.parametrize("endian", ["<", ">"])
def test_exif_exposure_time_from_jpeg(tmp_path, endian):
    _exif_jpeg(tmp_path / "a.jpg", (1, 250), endian)
    assert hdr_merge.exif_exposure_time(tmp_path / "a.jpg") == pytest.approx(1 / 250)
    assert cv2.imread(str(tmp_path / "a.jpg")) is not None          # still a valid JPEG
    cv2.imwrite(str(tmp_path / "b.jpg"), np.zeros((8, 8, 3), np.uint8))
    assert hdr_merge.exif_exposure_time(tmp_path / "b.jpg") is None


def test_brackets_take_exif_times_and_sort(tmp_path):
    paths = []
    for i, den in enumerate((30, 500, 125)):
        _exif_jpeg(tmp_path / f"{i}.jpg", (1, den))
        paths.append(tmp_path / f"{i}.jpg")
    _, times = hdr_merge.read_brackets(paths)
    assert times.tolist() == pytest.approx([1 / 500, 1 / 125, 1 / 30])


# --------------------------------------------------------------------------------- merge
def test_merge_recovers_radiance_and_response():
    rng = np.random.default_rng(1)
    radiance = np.exp(rng.uniform(np.log(0.05), np.log(80), size=(96, 128, 1))) * np.array([1.0, 0.8, 0.6])
    radiance = cv2.GaussianBlur(radiance.astype(np.float32), (0, 0), 1.0)
    imgs = brackets(radiance, TIMES)
    res = hdr_merge.merge(imgs, TIMES)
    # value 128 <-> exposure (128/255)^2.2, so radiance = merged x that
    got = res.radiance * (128 / 255) ** 2.2
    rel = np.abs(got - radiance) / radiance
    assert np.median(rel) < 0.01 and np.percentile(rel, 99) < 0.05
    z = np.arange(24, 232)
    known = (z / 255) ** 2.2 / (128 / 255) ** 2.2
    resp = res.response[z] / res.response[128]
    assert np.max(np.abs(resp / known[:, None] - 1)) < 0.05
    assert not res.clipped.any() and not res.warnings


def test_clipped_in_every_bracket_is_found_and_a_lower_bound():
    rng = np.random.default_rng(2)
    radiance = np.exp(rng.uniform(np.log(0.05), np.log(80), size=(64, 64, 1))).repeat(3, -1).astype(np.float32)
    radiance[20:30, 20:30] = 5000.0                          # a sun, clipped even at 1/500 s
    radiance[40:50, 40:50] = 300.0                           # bright, but not clipped at 1/500 s
    res = hdr_merge.merge(brackets(radiance, TIMES), TIMES)
    assert res.clipped[20:30, 20:30].all() and res.clipped.sum() == 100
    assert "100 pixels" in res.warnings[0] and "clipped in every bracket" in res.warnings[0]
    scale = (128 / 255) ** 2.2
    sun = res.radiance[25, 25] * scale
    lower = (250 / 255) ** 2.2 / TIMES[0]
    assert np.allclose(sun, lower, rtol=0.05)               # the lower bound, not "far too dark"
    assert np.allclose(res.radiance[45, 45] * scale, 300, rtol=0.03)


def test_grey_card_repair_restores_the_suns_energy():
    h = 64
    env = np.full((h, 2 * h, 3), 0.5, np.float64)
    d = texel_directions(h, 2 * h)
    sun_dir = np.array([0.5, 0.3, 0.8]) / np.linalg.norm([0.5, 0.3, 0.8])
    sun = d @ sun_dir > np.cos(np.radians(4))
    env[sun] = (4000.0, 3800.0, 3500.0)
    albedo = 0.18
    cosine = np.clip(d @ sun_dir, 0, None) * texel_solid_angles(h, 2 * h)
    card = albedo / np.pi * np.einsum("hw,hwc->c", cosine, env)          # what the card shows
    clipped_env = env.copy()
    clipped_env[sun] = 150.0                                              # the lower bound
    repaired, scale = hdr_merge.repair_clipped(clipped_env, sun, card, albedo, sun_dir)
    assert scale > 20
    sun_energy = lambda e: np.einsum("hw,hwc->c", (cosine * sun), e)
    assert np.allclose(sun_energy(repaired), sun_energy(env), rtol=1e-6)
    assert np.array_equal(repaired[~sun], clipped_env[~sun].astype(np.float32))
    with pytest.raises(PlateLightError, match="does not face"):
        hdr_merge.repair_clipped(clipped_env, sun, card, albedo, -sun_dir)
    with pytest.raises(PlateLightError, match="darker"):
        hdr_merge.repair_clipped(clipped_env, sun, card * 0.001, albedo, sun_dir)


# ---------------------------------------------------------------------------- mirror ball
def _tilted_camera():
    yaw, pitch = np.radians(30), np.radians(-20)
    base = mirror_ball.default_camera_rotation()
    rx = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    return mirror_ball.rotation_z(np.degrees(yaw)) @ base @ rx


@pytest.mark.parametrize("camera", ["default", "tilted"])
def test_unwrap_inverts_the_forward_model(camera):
    env = smooth_env(64)
    rot = mirror_ball.default_camera_rotation() if camera == "default" else _tilted_camera()
    photo = forward_ball(env, 200, 90.0, rot)
    ball = mirror_ball.Ball(99.5, 99.5, 90.0)
    probe, conf = mirror_ball.unwrap(photo, ball, 32, None if camera == "default" else rot)
    truth = downsample_area(env, 32)
    mask = mirror_ball.view_angle_deg(32, rot) < 120
    rel = np.abs(probe - truth).sum(-1) / truth.sum(-1)
    assert np.median(rel[mask]) < 0.02
    assert conf.min() < 0.5 and conf.max() == 1


def sun_env(sun, height=512, radius_deg=0.5, value=2e4):
    """smooth_env with a small hot sun (1 deg across), far smaller than a probe texel."""
    env = smooth_env(height)
    d = texel_directions(height, 2 * height)
    env[d @ (np.asarray(sun) / np.linalg.norm(sun)) > np.cos(np.radians(radius_deg))] = value
    return env


def band_powers(latlong):
    """Power of SH bands 0, 1, 2 (grey): what the diffuse and glossy maps are made of."""
    c = sh.project_exact(np.asarray(latlong, np.float64), 2).mean(-1)
    return np.array([c[0] ** 2, (c[1:4] ** 2).sum(), (c[4:9] ** 2).sum()])


@pytest.mark.parametrize("sun", [(0.3, -0.5, 0.6), (0.1, -0.3, 0.9)])
def test_unwrap_keeps_a_small_suns_energy(sun):
    """A sun smaller than a texel, where each texel covers many photo pixels: a texel that
    sampled one point caught the sun whole or missed it (band powers 0.19x-1.6x off)."""
    env = sun_env(sun)
    photo = forward_ball(env, 260, 120.0, mirror_ball.default_camera_rotation(), ss=8)
    probe, _ = mirror_ball.unwrap(photo, mirror_ball.Ball(129.5, 129.5, 120.0), 64)
    ratio = band_powers(probe) / band_powers(downsample_area(env, 64))
    assert np.all(np.abs(ratio - 1) < 0.05), ratio


def test_find_ball_subpixel():
    env = smooth_env(64)
    photo = forward_ball(env, 240, 83.3, mirror_ball.default_camera_rotation(), background=0.05)
    shifted = np.zeros((240, 320, 3), np.float32) + 0.05
    shifted[:, 47:287] = photo
    eight_bit = np.round(tone(shifted * 0.8) * 255).astype(np.uint8)
    ball = mirror_ball.find_ball(eight_bit)
    assert abs(ball.cx - (119.5 + 47)) < 0.5 and abs(ball.cy - 119.5) < 0.5 and abs(ball.radius - 83.3) < 0.5


# ------------------------------------------------------------------------------ CLI, bad input
@pytest.fixture(scope="module")
def ball_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ballfiles")
    env = smooth_env(64)
    photo = forward_ball(env, 160, 70.0, mirror_ball.default_camera_rotation(), background=0.05)
    paths = []
    for i, img in enumerate(brackets(photo, TIMES, scale=2.0)):
        paths.append(folder / f"b{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    return folder, paths, env


def test_probe_cli_contract(ball_files, tmp_path):
    folder, paths, env = ball_files
    out = tmp_path / "probe.exr"
    proc = support.run_cli("probe", *paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out,
                           "--height", 32, "--report", tmp_path / "r.json")
    assert proc.returncode == 0, proc.stderr
    probe = read_exr(out)
    assert probe.shape == (32, 64, 3)
    # the report lists the finder's circles, best first, and draws them on the middle bracket
    report = json.loads((tmp_path / "r.json").read_text())
    assert abs(report["candidates"][0]["cx"] - report["ball"]["cx"]) < 0.01     # (rounded to 0.01 px)
    picture = cv2.imread(str(tmp_path / "r.png"))
    assert picture.shape[:2] == (160, 160)
    green = (picture[..., 1] > 180) & (picture[..., 0] < 120) & (picture[..., 2] < 120)
    ring = np.hypot(*(np.mgrid[0:160, 0:160] - 79.5)) - 70.0
    # the circle used, where the ball is (the rest of the green: its confidence's label)
    assert green.sum() > 200 and (np.abs(ring[green]) < 4).mean() > 0.7
    truth = downsample_area(env, 32)
    s = (128 / 255) ** 2.2 / 2.0
    mask = mirror_ball.view_angle_deg(32) < 120
    rel = np.abs(probe * s - truth).sum(-1) / truth.sum(-1)
    assert np.median(rel[mask]) < 0.03
    # turning the probe about +Z by 90 deg moves it by a quarter of the width
    out2 = tmp_path / "rot.exr"
    proc = support.run_cli("probe", *paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out2,
                           "--height", 32, "--rotate-z", 90)
    assert proc.returncode == 0, proc.stderr
    assert np.allclose(np.roll(probe, -16, axis=1), read_exr(out2), rtol=1e-4, atol=1e-6)
    # per-channel response curves: same scene, within a percent or two of the shared curve
    proc = support.run_cli("probe", *paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out2,
                           "--height", 32, "--per-channel-response")
    assert proc.returncode == 0, proc.stderr
    assert np.median(np.abs(read_exr(out2) / probe - 1)) < 0.03


def _cli_error(*args):
    proc = support.run_cli("probe", *args)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


def test_probe_bad_inputs(ball_files, tmp_path):
    folder, paths, _ = ball_files
    out = tmp_path / "p.exr"
    times = "1/500,1/125,1/30,1/8"
    assert "No EXIF exposure time in b0.png, b1.png" in _cli_error(*paths, "--out", out)
    # EXIF missing from one bracket only: that one is named
    exif = []
    for i, den in enumerate((500, 125, 30)):
        img = cv2.imread(str(paths[i]))
        ok, jpg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])
        exif.append(tmp_path / f"e{i}.jpg")
        exif[-1].write_bytes(jpg.tobytes())
        if i != 1:
            _add_exif(exif[-1], (1, den))
    assert "No EXIF exposure time in e1.jpg; give them with --exposures" in _cli_error(*exif, "--out", out)
    assert "2 exposure times were given for 1 photo" in _cli_error(paths[0], "--exposures", "1,2", "--out", out)
    big = tmp_path / "big.png"
    cv2.imwrite(str(big), np.zeros((10, 12, 3), np.uint8))
    assert "different sizes" in _cli_error(paths[0], big, "--exposures", "1/500,1/125", "--out", out)
    junk = tmp_path / "junk.jpg"
    junk.write_text("no image here")
    assert "Cannot read the bracket" in _cli_error(paths[0], junk, "--exposures", "1/500,1/125", "--out", out)
    assert "Bracket not found" in _cli_error(paths[0], tmp_path / "nope.jpg", "--exposures", "1,2", "--out", out)
    assert "same exposure time" in _cli_error(*paths[:2], "--exposures", "0.01,0.01", "--out", out)
    assert "2 exposure times were given for 4 brackets" in _cli_error(*paths, "--exposures", "1,2", "--out", out)
    flat = []
    for i in range(3):
        flat.append(tmp_path / f"flat{i}.png")
        cv2.imwrite(str(flat[-1]), np.full((100, 100, 3), 60 + 40 * i, np.uint8))
    assert "No mirror ball was found" in _cli_error(*flat, "--exposures", "1/100,1/50,1/25", "--out", out)
    assert "The ball is cut by the frame (76 % of its radius" in _cli_error(*paths, "--exposures", times, "--ball", "150,80,40",
                                                     "--out", out)
    assert not out.exists()


def test_probe_aligned_on_a_marker_seen_in_the_photos(tmp_path):
    """A marker on the floor beside the ball gives the photo's camera rotation: the probe comes
    out in the marker's frame although the camera looked down 40 deg and turned 25 deg."""
    from platelight.addon.capture.boards import target_image
    from platelight.addon.capture.targets import MarkerTarget
    from test_capture_tracking import warp_target

    pitch, yaw = np.radians(-40), 25.0
    rx = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    rot = mirror_ball.rotation_z(yaw) @ mirror_ball.default_camera_rotation() @ rx
    size, f = (480, 320), 500.0
    # the marker 0.3 m to the camera's right and 0.9 m ahead, seen through a pinhole of that rotation
    camera = np.eye(4)
    camera[:3, :3] = rot
    camera[:3, 3] = -rot @ np.array([0.3, 0.0, -0.9])
    target = MarkerTarget("DICT_4X4_50", 0.16)
    tex = target_image(target, dpi=3000 * 0.0254, margin_m=0.02)
    marker = (warp_target(tex, target.extent, camera, size=size, f=f, ss=2, background=0.3)
              .astype(np.float32) / 255.0) ** 2.2
    photo = np.repeat(marker[..., None], 3, axis=-1)
    env = smooth_env(64)
    ball = forward_ball(env, 200, 90.0, rot, background=0.3)
    photo[60:260, 20:220] = ball                       # the ball (orthographic) on the left
    paths = []
    for i, img in enumerate(brackets(photo, TIMES, scale=2.0)):
        paths.append(tmp_path / f"b{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    out = tmp_path / "aligned.exr"
    proc = support.run_cli("probe", *paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out,
                           "--height", 32, "--ball", "119.5,159.5,90", "--align-marker", 0.16,
                           "--focal-px", f)
    assert proc.returncode == 0, proc.stderr
    probe = read_exr(out) * (128 / 255) ** 2.2 / 2.0
    truth = downsample_area(env, 32)
    mask = mirror_ball.view_angle_deg(32, rot) < 120
    rel = np.abs(probe - truth).sum(-1) / truth.sum(-1)
    print(f"aligned: median {np.median(rel[mask]):.4f}")
    assert np.median(rel[mask]) < 0.03
    # without the marker the default (front view) orientation is wrong, and it shows
    proc = support.run_cli("probe", *paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out,
                           "--height", 32, "--ball", "119.5,159.5,90")
    wrong = read_exr(out) * (128 / 255) ** 2.2 / 2.0
    wrong_rel = np.median((np.abs(wrong - truth).sum(-1) / truth.sum(-1))[mask])
    print(f"front view assumed: median {wrong_rel:.4f}")
    assert wrong_rel > 0.1
    msg = _cli_error(*paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out, "--ball", "119.5,159.5,90",
                     "--align-marker", 0.16)
    assert "needs the camera's focal length" in msg
    msg = _cli_error(*paths, "--exposures", "1/500,1/125,1/30,1/8", "--out", out, "--ball", "119.5,159.5,90",
                     "--align-marker", 0.16, "--focal-px", f, "--dictionary", "DICT_6X6_250")
    assert "The alignment DICT_6X6_250 marker was not found in any bracket." in msg


def sun_and_card_photos(folder):
    """Brackets of a ball under a 6-degree sun clipped in all of them, with a grey card (albedo
    0.18, facing the sun) at pixels (220, 20)-(260, 60). Returns the paths, the cosine weights
    towards the sun per texel of a 64x128 probe and the true irradiance there."""
    h = 64
    env = smooth_env(h).astype(np.float64)
    d = texel_directions(h, 2 * h)
    sun_dir = np.array([0.3, -0.6, 0.74]) / np.linalg.norm([0.3, -0.6, 0.74])
    env[d @ sun_dir > np.cos(np.radians(6))] = (3000.0, 2900.0, 2700.0)
    cosine = np.clip(d @ sun_dir, 0, None) * texel_solid_angles(h, 2 * h)
    irradiance = np.einsum("hw,hwc->c", cosine, env)
    photo = np.full((200, 280, 3), 0.3, np.float32)
    photo[:, :200] = forward_ball(env.astype(np.float32), 200, 90.0, mirror_ball.default_camera_rotation(),
                                  background=0.3)
    photo[20:60, 220:260] = 0.18 / np.pi * irradiance          # the card, facing the sun
    paths = []
    for i, img in enumerate(brackets(photo, TIMES, scale=2.0)):
        paths.append(folder / f"b{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    return paths, cosine, irradiance, sun_dir


def test_probe_cli_grey_card_repairs_a_clipped_sun(tmp_path):
    """A sun clipped in every bracket and a grey card facing it in the same photos: the repaired
    probe lights a surface facing the sun as the card was lit."""
    import json

    paths, cosine, irradiance, sun_dir = sun_and_card_photos(tmp_path)
    common = [*paths, "--exposures", "1/500,1/125,1/30,1/8", "--height", 64, "--ball", "99.5,99.5,90"]
    out, report = tmp_path / "probe.exr", tmp_path / "r.json"
    proc = support.run_cli("probe", *common, "--out", out, "--report", report)
    assert proc.returncode == 0 and "clipped in every bracket" in proc.stderr
    scale = (128 / 255) ** 2.2 / 2.0
    lit = lambda probe: np.einsum("hw,hwc->c", cosine, probe.astype(np.float64) * scale)
    before = lit(read_exr(out))
    clipped = json.loads(report.read_text())["clipped"]
    assert np.degrees(np.arccos(np.dot(clipped["direction"], sun_dir))) < 2
    proc = support.run_cli("probe", *common, "--out", out, "--report", report, "--grey-card", "220,20,260,60")
    assert proc.returncode == 0, proc.stderr
    assert "repaired from the grey card" in proc.stderr
    after = lit(read_exr(out))
    print(f"irradiance / truth: clipped {before / irradiance}, repaired {after / irradiance}")
    assert np.all(before < 0.5 * irradiance)
    assert np.allclose(after, irradiance, rtol=0.03)
    assert "not inside" in _cli_error(*common, "--out", out, "--grey-card", "270,20,300,60")
