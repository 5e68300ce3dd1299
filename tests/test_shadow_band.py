"""The band of the shadow panorama that the bake renders (addon/compositing/baked_shadows.py):
every point of every phantom box falls in it, and a floor's is about half the panorama."""
from __future__ import annotations

import math

import numpy as np

from platelight.addon.compositing import baked_shadows as engine


def point_rows(centre, points, height):
    """The panorama row (first row the top) each point is seen in."""
    offset = points - centre
    elevation = np.arctan2(offset[:, 2], np.linalg.norm(offset[:, :2], axis=1))
    return np.floor((0.5 - elevation / math.pi) * height).astype(int)


def test_every_point_of_every_box_lies_in_the_band():
    rng = np.random.default_rng(3)
    height = 256
    for _ in range(300):
        centre = rng.uniform(-2, 2, 3)
        boxes = []
        for _ in range(rng.integers(1, 4)):
            low = rng.uniform(-4, 4, 3)
            boxes.append((low, low + rng.uniform(0.01, 3, 3)))
        band = engine.panorama_rows(centre, boxes, height)
        first, last = band if band is not None else (0, height)
        for low, high in boxes:
            points = rng.uniform(low, high, (400, 3))
            # the faces too, where the extremes lie
            for axis in range(3):
                points[:50, axis] = low[axis]
                points[50:100, axis] = high[axis]
            rows = point_rows(centre, points, height)
            assert rows.min() >= first and rows.max() < last, (centre, low, high, band, rows.min(), rows.max())


def test_a_floor_under_the_centre_is_the_lower_half():
    height = 512
    first, last = engine.panorama_rows(np.array([0.0, 0.0, 1.9]),
                                       [(np.array([-200.0, -200.0, 0.0]), np.array([200.0, 200.0, 0.0]))], height)
    # its far corners, 283 m off, lie 0.4 degrees below the horizon: one row below the middle
    assert last == height and first == height // 2 + 1 - engine.ROW_MARGIN
    # a floor 3 m wide seen from 2 m above: the steep rows only
    first, last = engine.panorama_rows(np.array([0.0, 0.0, 2.0]),
                                       [(np.array([-1.5, -1.5, 0.0]), np.array([1.5, 1.5, 0.0]))], height)
    steepest = math.atan2(-2.0, math.hypot(1.5, 1.5))
    assert first == math.floor((0.5 - steepest / math.pi) * height) - engine.ROW_MARGIN and last == height


def test_a_phantom_around_the_centre_renders_the_whole_panorama():
    walls = [(np.array([-3.0, -3.0, 0.0]), np.array([3.0, 3.0, 4.0]))]
    assert engine.panorama_rows(np.array([0.0, 0.0, 1.5]), walls, 256) is None
    assert engine.panorama_rows(np.array([0.0, 0.0, 1.5]), [], 256) is None


def test_the_catcher_pass_becomes_the_ratio_only_where_a_catcher_was_seen():
    """catcher_ratio: the Shadow Catcher pass where the Combined alpha says catcher (0), 1 over
    the sky (1; the denoised pass there is 1 smoothed), blended at the horizon, 1 outside the
    rendered rows (black there), clamped as the two renders' ratio."""
    caught = np.zeros((8, 4, 4), np.float32)
    caught[2:6, :, :3] = [[0.5], [0.99], [6.0], [0.5]]              # shadow, sky, a clamped bounce, horizon
    caught[2:6, 1, 3], caught[2:6, 3, 3] = 1.0, 0.5
    ratio = engine.catcher_ratio(caught, (2, 6))
    assert (ratio[:2] == 1).all() and (ratio[6:] == 1).all()
    assert np.allclose(ratio[2:6, :, 0], [0.5, 1.0, engine.RATIO_CLAMP, 0.75])
    assert (ratio[2:6, 1] == 1).all()


def test_removing_old_frames_keeps_the_kept_frames_and_every_other_file(tmp_path):
    """A per-frame bake drops the files of frames no longer in the shot, and nothing else: the
    kept frames, the still bake's files and a user's own files in the folder stay."""
    moving = tmp_path / engine.MOVING_FOLDER
    moving.mkdir()
    others = ["shadow_ratio.exr", "shadow_ratio_notes.exr", "distance_0003_backup.exr", "readme.txt"]
    for name in [n for f in (1, 2, 3, 12) for n in engine.moving_filenames(f)] + others:
        (moving / name).write_bytes(b"")
    removed = engine.remove_moving_frames(str(tmp_path), keep=(1, 2))
    assert removed == sorted(n for f in (3, 12) for n in engine.moving_filenames(f))
    assert engine.has_moving_frames(str(tmp_path), (1, 2)) and not engine.has_moving_frames(str(tmp_path), (3,))
    assert all((moving / name).exists() for name in others)
    assert engine.remove_moving_frames(str(tmp_path / "nothing here")) == []
