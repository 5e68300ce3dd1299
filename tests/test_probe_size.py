"""Probe sizing from the object's size on screen (addon/bake/probe_size.py), against a brute-force
projection of the sphere's silhouette through a pinhole camera."""
import math

import numpy as np
import pytest

from platelight.addon.bake.probe_size import auto_probe_height, projected_extent

# Blender's view_frame() of a 50 mm lens on a 36 mm sensor (fit AUTO, landscape): x = ±0.36/2 at
# z = -0.5 (its corners lie at the lens/sensor ratio, scaled).
CORNERS = [(0.36, 0.2025, -1.0), (0.36, -0.2025, -1.0), (-0.36, -0.2025, -1.0), (-0.36, 0.2025, -1.0)]


def look_at(eye, target):
    """Camera-to-world matrix of a camera at ``eye`` looking at ``target`` (Z up)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
    return m


def sphere_points(centre, radius, n=20000):
    rng = np.random.default_rng(0)
    d = rng.normal(size=(n, 3))
    return np.asarray(centre) + radius * d / np.linalg.norm(d, axis=1, keepdims=True)


def pinhole_extent(m, corners, width_px, pts):
    """The same by the textbook pinhole: x_px = f·x/(-z) with f from the 36 mm film at 50 mm."""
    f_px = width_px * 50.0 / 36.0
    local = (pts - m[:3, 3]) @ m[:3, :3]
    x = f_px * local[:, 0] / -local[:, 2]
    y = f_px * local[:, 1] / -local[:, 2]
    return max(x.max() - x.min(), y.max() - y.min())


@pytest.mark.parametrize("eye,centre,radius", [
    ((-2.2, -4.6, 2.2), (0.0, 0.0, 0.5), 0.5),        # the benchmark's view
    ((0.0, -3.0, 0.5), (0.8, 0.0, 0.5), 0.3),         # off axis, near the frame's edge
    ((0.0, -20.0, 1.0), (0.0, 0.0, 1.0), 1.0),        # far away
])
def test_extent_is_the_pinhole_projection_of_the_surface(eye, centre, radius):
    m = look_at(eye, (0.0, 0.0, 0.5))
    pts = sphere_points(centre, radius)
    assert projected_extent(m, CORNERS, 480, pts) == pytest.approx(pinhole_extent(m, CORNERS, 480, pts), rel=1e-9)


def test_a_sphere_on_axis_is_as_wide_as_its_silhouette():
    m = look_at((0.0, -10.0, 0.0), (0.0, 0.0, 0.0))
    f_px = 480 * 50.0 / 36.0
    silhouette = 2 * f_px * 0.5 / np.sqrt(10.0 ** 2 - 0.5 ** 2)        # tangent cone, on axis
    assert projected_extent(m, CORNERS, 480, sphere_points((0, 0, 0), 0.5, 200000)) == pytest.approx(silhouette, rel=0.01)


def test_a_point_behind_the_camera_asks_for_the_largest_probe():
    m = look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    assert math.isinf(projected_extent(m, CORNERS, 480, sphere_points((0.0, 0.2, 0.0), 0.5)))
    assert auto_probe_height(float("inf"), 64, 1024) == 1024


def test_orthographic_extent_is_the_object_over_the_film():
    corners = [(2.0, 1.0, 0.0), (2.0, -1.0, 0.0), (-2.0, -1.0, 0.0), (-2.0, 1.0, 0.0)]
    pts = sphere_points((0.0, 0.0, -5.0), 0.5, 200000)
    assert projected_extent(np.eye(4), corners, 400, pts, orthographic=True) == pytest.approx(100.0, rel=0.01)


@pytest.mark.parametrize("diameter,minimum,maximum,height", [
    (122, 64, 1024, 256),       # twice the width, rounded up to a power of two
    (128, 64, 1024, 256),
    (129, 64, 1024, 512),
    (10, 64, 1024, 64),         # never below the scene's probe height
    (5000, 64, 1024, 1024),     # never above the maximum
    (0, 64, 1024, 64),
    (300, 64, 32, 32),          # the maximum wins over the minimum
])
def test_auto_height(diameter, minimum, maximum, height):
    assert auto_probe_height(diameter, minimum, maximum) == height


def test_small_probes_get_more_samples_at_no_more_cost_than_a_128_row_probe():
    from platelight.addon.bake.probe_size import MAX_SAMPLE_FACTOR, SAMPLE_ROWS, samples_for
    assert samples_for(16, 64) == 16 * MAX_SAMPLE_FACTOR  # the default 64-row probe: capped
    assert samples_for(16, 32) == 16 * MAX_SAMPLE_FACTOR  # capped
    assert samples_for(16, SAMPLE_ROWS) == 16             # at and above SAMPLE_ROWS: Probe Samples
    assert samples_for(16, 512) == 16
    for height in (40, 64, 92, 100, 120):
        samples = samples_for(16, height)
        assert 16 < samples <= 16 * MAX_SAMPLE_FACTOR
        # rays per probe: never above a SAMPLE_ROWS probe's at Probe Samples (rounding aside)
        assert samples * height * height <= 16 * SAMPLE_ROWS * SAMPLE_ROWS * 1.01
    assert samples_for(16, 100) == 26                     # (128 / 100)^2 = 1.64 times
    assert samples_for(1, 512) == 1 and samples_for(1, 8) == MAX_SAMPLE_FACTOR
