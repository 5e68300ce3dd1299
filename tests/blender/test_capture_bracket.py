"""A chrome ball in front of the very HDRI it reflects, filmed at five exposures: the probe CLI
finds the ball and merges the brackets into a probe with the HDRI's light.

Seen by an orthographic camera, the background around the ball is the direction straight
ahead, and the ball's outermost rim reflects the direction straight behind it: the same
light. The rim's step is then only the reflectance's loss (-25 % for a chrome of 0.75), far
weaker than the compressed reflections just inside it."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import capture_render as cr
import support
from platelight.addon.capture import mirror_ball
from platelight.addon.exr_io import read_exr
from platelight.addon.ibl import sh
from platelight.addon.ibl.equirect import downsample_area

SIZE = 600                       # px, the frame
DIAMETER = 460                   # px, the ball
REFLECTANCE = 0.75
TIMES = [1 / 16, 1 / 4, 1, 4, 16]
HDRI = "forest"


def band_powers(latlong: np.ndarray) -> np.ndarray:
    """Power of SH bands 0, 1, 2 (sum of squared coefficients, grey: mean of RGB); the same
    for any rotation of the map."""
    c = sh.project_exact(np.asarray(latlong, np.float64), 2).mean(-1)
    return np.array([c[0] ** 2, (c[1:4] ** 2).sum(), (c[4:9] ** 2).sum()])


@pytest.fixture(scope="module")
def bracket(bpy_module, tmp_path_factory, studio_hdris):
    folder = tmp_path_factory.mktemp("bracket")
    info = cr.render_mirror_ball(bpy_module, studio_hdris[HDRI], folder / "ball.exr", size=SIZE, samples=4,
                                 ortho_scale=2.0 * SIZE / DIAMETER, reflectance=REFLECTANCE)
    radiance = read_exr(folder / "ball.exr")
    # the brightest pixel just below white in the shortest exposure: nothing is clipped in all
    scale = 0.9 / TIMES[0] / float(radiance.max())
    paths = []
    for i, img in enumerate(cr.make_brackets(radiance, TIMES, scale)):
        paths.append(folder / f"bracket_{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    return folder, paths, info, scale, studio_hdris[HDRI]


def test_ball_before_its_own_hdri_found_and_merged(bracket):
    folder, paths, info, scale, hdri = bracket
    out, report = folder / "probe.exr", folder / "report.json"
    proc = support.run_cli("probe", *paths, "--exposures", ",".join(f"{t:g}" for t in TIMES), "--out", out,
                           "--height", 256, "--reflectance", REFLECTANCE, "--report", report)
    assert proc.returncode == 0, proc.stderr
    ball = json.loads(report.read_text())["ball"]
    r = info["radius"]
    centre = np.hypot(ball["cx"] - info["cx"], ball["cy"] - info["cy"]) / r
    radius = abs(ball["radius"] - r) / r
    # the probe is unwrapped with the default camera (no camera given), which is the render's
    assert np.allclose(info["camera_to_world"][:3, :3], mirror_ball.default_camera_rotation())
    # absolute scale: value 128 <-> radiance x reflectance x time x scale = (128/255)^2.2
    probe = read_exr(out) * ((128 / 255) ** 2.2 / scale)
    truth = downsample_area(read_exr(hdri)[..., :3], 256)
    ratio = band_powers(probe) / band_powers(truth)
    print(f"ball ({ball['cx']:.2f}, {ball['cy']:.2f}) r {ball['radius']:.2f}, confidence {ball['confidence']}: "
          f"centre {100 * centre:.2f} %, radius {100 * radius:.2f} % of r; SH band powers / truth {np.round(ratio, 3)}")
    assert centre < 0.02 and radius < 0.02
    assert np.all(np.abs(ratio - 1) < 0.25), ratio
