"""A small sample of the synthetic ball corpus (tests/ball_corpus.py) in the suite; the whole of
it runs in `make bench` (docs/bench/capture.md)."""
from __future__ import annotations

import numpy as np
import pytest

import ball_corpus as bc
from platelight.addon.capture import ball_finder
from platelight.addon.errors import PlateLightError

SAMPLE = [
    bc.Spec("hard_sun", 2400, 1600, 0.06, (0.5, -0.3), camera="perspective", backdrop="scene", holder="stand"),
    bc.Spec("forest", 1200, 900, 0.3, (-0.8, 0.6), camera="perspective", backdrop="clutter", holder="stand",
            noise=0.02, jpeg=95),
    bc.Spec("overcast", 1600, 1200, 0.5, (0.2, 0.1), camera="orthographic", backdrop="bright", exposure=1),
    bc.Spec("night_street", 1000, 1000, 0.95, camera="perspective", backdrop="dark", exposure=-1),
    bc.Spec("city", 1600, 1200, 0.2, (-0.5, 0.5), camera="orthographic", backdrop="scene", holder="hand"),
    # JPEG rings just outside a bright rim on a dark backdrop: the last ripple is not the rim
    bc.Spec("hard_sun", 1000, 1000, 0.95, camera="perspective", backdrop="dark", jpeg=90),
]
WITHOUT = [bc.Spec("hard_sun", 1600, 900, 0.0, backdrop="clutter"), bc.Spec("lamp_room", 1200, 900, 0.0)]


@pytest.mark.parametrize("spec", SAMPLE, ids=lambda s: s.label)
def test_corpus_ball_found_within_two_percent(spec):
    photo, truth, _ = bc.render(spec, seed=3)
    centre, radius = bc.score(ball_finder.find_ball(photo), truth)
    assert centre < 0.02 and radius < 0.02, (centre, radius)


@pytest.mark.parametrize("spec", WITHOUT, ids=lambda s: s.label)
def test_corpus_photo_without_a_ball_is_refused(spec):
    photo, truth, _ = bc.render(spec, seed=3)
    assert truth is None
    with pytest.raises(PlateLightError, match="No mirror ball was found"):
        ball_finder.find_ball(photo)


def test_truth_is_the_silhouette():
    """The orthographic ball's measured silhouette is the circle it was drawn with."""
    spec = bc.Spec("overcast", 800, 600, 0.5, (0.3, -0.2), camera="orthographic")
    _, truth, _ = bc.render(spec)
    r = 0.25 * 600
    assert abs(truth["rx"] / r - 1) < 0.002 and abs(truth["ry"] / r - 1) < 0.002
    assert abs(truth["cx"] - (399.5 + 0.3 * (400 - r))) < 0.05 and abs(truth["cy"] - (299.5 - 0.2 * (300 - r))) < 0.05


def test_lens_given_unwraps_an_off_centre_ball_along_its_ray():
    """A ball in the frame's corner is seen from the side: with the lens known the unwrap looks
    along the ball's ray, and the probe's light comes from where the environment's does."""
    from platelight.addon.capture import mirror_ball
    from platelight.addon.capture.intrinsics import Intrinsics
    from platelight.addon.ibl import sh

    spec = bc.Spec("forest", 1600, 1200, 0.25, (0.9, -0.9), reflectance=0.8, yaw=30)
    _, truth, radiance = bc.render(spec)
    ball = mirror_ball.Ball(truth["cx"], truth["cy"], truth["rx"], truth["ry"])
    rot = mirror_ball.rotation_z(spec.yaw) @ mirror_ball.default_camera_rotation()
    lens = Intrinsics.from_focal_px(bc.focal_px(spec), spec.width, spec.height)
    env = sh.project_exact(bc.environment(spec.env).astype(float), 2).mean(-1)

    def error(r):
        c = sh.project_exact(mirror_ball.unwrap(radiance, ball, 64, r, spec.reflectance)[0].astype(float), 2).mean(-1)
        return np.linalg.norm(c - env) / np.linalg.norm(env)
    along_axis, along_ray = error(rot), error(rot @ mirror_ball.aim_rotation(ball, lens))
    assert along_ray < 0.1 and along_axis > 2 * along_ray, (along_axis, along_ray)
