"""Irradiance grids (addon/ibl/irradiance_grid.py) against analytic irradiance and the maps'
own rules: a point above a floor with a dark disc under it, the sky-only case, buried points,
and the atlas look-up the shader builds."""
import numpy as np
import pytest

from platelight.addon.ibl import irradiance_grid as ig
from platelight.addon.ibl.equirect import dir_to_uv, sample_bilinear, texel_directions
from platelight.addon.ibl.distance import FAR
from platelight.addon.ibl.maps import DIFFUSE_LMAX_EXACT, compute_maps

FLOOR = 1.0          # the floor lies this far below the probe's centre
DISC, L_DISC, L_FLOOR, L_SKY = 0.5, 0.05, 0.6, 2.0


def floor_scene(height):
    """Radiance and distance panoramas of a probe FLOOR above an infinite floor of radiance
    L_FLOOR with a disc of radius DISC and radiance L_DISC right under the centre, sky L_SKY."""
    def panoramas(h):
        d = texel_directions(h, 2 * h)
        down = d[..., 2] < -1e-9
        t = np.where(down, FLOOR / np.where(down, -d[..., 2], 1.0), FAR)
        hit = d * t[..., None]
        on_disc = down & (np.hypot(hit[..., 0], hit[..., 1]) < DISC)
        radiance = np.where(down, np.where(on_disc, L_DISC, L_FLOOR), L_SKY)
        return np.repeat(radiance[..., None], 3, axis=2).astype(np.float32), t.astype(np.float32)
    radiance, _ = panoramas(height)
    _, distance = panoramas(4 * height)
    return radiance, distance


def value_at(image, direction):
    u, v = dir_to_uv(np.asarray(direction, dtype=np.float64))
    return sample_bilinear(image, u, v)


@pytest.mark.parametrize("h", [0.2, 0.5, 0.8])
def test_a_point_over_a_dark_disc_sees_it_as_from_there(h):
    """Facing down from h above the disc's centre, the disc fills the form factor a²/(a²+h²) of
    the hemisphere and the lit floor the rest: E/π = L_disc F + L_floor (1 - F). The centre's
    own map (h = FLOOR) is what the paper's look-up reads at every height."""
    radiance, distance = floor_scene(256)
    offset = np.array([0.0, 0.0, -FLOOR + h])
    maps = ig.irradiance_maps(radiance, distance, [offset], 64, DIFFUSE_LMAX_EXACT)
    form = DISC ** 2 / (DISC ** 2 + h ** 2)
    expected = L_DISC * form + L_FLOOR * (1.0 - form)
    got = value_at(maps[0], [0, 0, -1])[0]
    assert got == pytest.approx(expected, rel=0.02)
    centre = compute_maps(radiance, which=("diffuse",)).maps["diffuse"]
    at_centre = value_at(centre, [0, 0, -1])[0]
    form_c = DISC ** 2 / (DISC ** 2 + FLOOR ** 2)
    assert at_centre == pytest.approx(L_DISC * form_c + L_FLOOR * (1 - form_c), rel=0.02)
    # facing up, every height sees the whole sky
    assert value_at(maps[0], [0, 0, 1])[0] == pytest.approx(L_SKY, rel=0.01)


def test_without_surfaces_every_point_sees_what_the_centre_sees():
    rng = np.random.default_rng(3)
    radiance = rng.uniform(0.1, 3.0, (32, 64, 3)).astype(np.float32)
    distance = np.full((128, 256), FAR, np.float32)
    maps = ig.irradiance_maps(radiance, distance, [[0, 0, 0], [0.3, -0.2, 0.4]], 16, 48)
    centre = compute_maps(radiance, which=("diffuse",)).maps["diffuse"]
    np.testing.assert_allclose(maps[0], centre, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(maps[1], centre, rtol=2e-3, atol=1e-4)


def test_a_point_below_the_floor_is_pulled_in_front_of_it():
    _, distance = floor_scene(32)
    moved = ig.unburied(np.array([[0.0, 0.0, -1.5], [0.0, 0.0, 0.5], [0.3, 0.0, -0.5]]), distance)
    assert moved[0] == pytest.approx([0, 0, -ig.IN_FRONT * FLOOR], abs=1e-3)
    np.testing.assert_array_equal(moved[1:], [[0, 0, 0.5], [0.3, 0, -0.5]])


def test_grid_points_and_trilinear_weights_share_one_tile_order():
    lo, hi = np.array([-1.0, -2.0, 0.0]), np.array([1.0, 2.0, 3.0])
    points = ig.grid_points(lo, hi, 4)
    tiles, weights = ig.trilinear(lo, hi, 4, points)
    # at a grid point all the weight is on its own tile
    own = tiles[np.arange(len(points)), np.argmax(weights, axis=1)]
    np.testing.assert_array_equal(own, np.arange(len(points)))
    assert np.allclose(weights.max(axis=1), 1.0)
    # in between, the weights sum to 1 and reproduce a linear function of position exactly
    rng = np.random.default_rng(0)
    inside = rng.uniform(lo, hi, (50, 3))
    tiles, weights = ig.trilinear(lo, hi, 4, inside)
    assert np.allclose(weights.sum(axis=1), 1.0)
    f = points @ np.array([0.3, -1.2, 2.0])
    np.testing.assert_allclose((f[tiles] * weights).sum(axis=1), inside @ np.array([0.3, -1.2, 2.0]))
    # outside the box the nearest face's values hold (clamped)
    tiles_out, weights_out = ig.trilinear(lo, hi, 4, np.array([[5.0, 0.0, 1.0]]))
    tiles_in, weights_in = ig.trilinear(lo, hi, 4, np.array([[1.0, 0.0, 1.0]]))
    np.testing.assert_array_equal(tiles_out, tiles_in)
    np.testing.assert_allclose(weights_out, weights_in)


def image_bilinear(image, x, y):
    """A plain image's bilinear filter (Blender's Image Texture: texel centres at (i + 0.5)/W,
    v = 0 at the bottom row, clamped at the edges)."""
    h, w = image.shape[:2]
    px, py = x * w - 0.5, (1.0 - y) * h - 0.5
    x0, y0 = np.floor(px).astype(int), np.floor(py).astype(int)
    fx, fy = (px - x0)[..., None], (py - y0)[..., None]
    xs = [np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)]
    ys = [np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)]
    top = image[ys[0], xs[0]] * (1 - fx) + image[ys[0], xs[1]] * fx
    bottom = image[ys[1], xs[0]] * (1 - fx) + image[ys[1], xs[1]] * fx
    return top * (1 - fy) + bottom * fy


def test_the_atlas_reads_each_map_as_an_environment_texture_would():
    rng = np.random.default_rng(1)
    maps = rng.uniform(0, 1, (5, 8, 16, 3)).astype(np.float32)
    image = ig.atlas(maps)
    assert image.shape == (8 + 2 * ig.PAD, 5 * (16 + 2 * ig.PAD), 3)
    dirs = rng.normal(size=(400, 3))
    u, v = dir_to_uv(dirs)
    u = np.concatenate([u, [0.0, 1.0, 0.001, 0.999]])      # across the seam
    v = np.concatenate([v, [0.5, 0.5, 0.999, 0.001]])      # near the poles
    for tile in range(5):
        x, y = ig.atlas_uv(tile, u, v, 5, 8)
        np.testing.assert_allclose(image_bilinear(image, x, y), sample_bilinear(maps[tile], u, v),
                                   atol=1e-6)


def test_a_large_probe_is_analysed_downsampled_with_the_same_irradiance(monkeypatch):
    """A probe sized to a mirror can be 1024 px high; each grid point's panorama is built at
    ANALYSIS_HEIGHT at most. Against the full-resolution analysis (the dark-disc floor seen from
    0.2 m, the sharpest case here) the maps agree within 1 % everywhere."""
    radiance, distance = floor_scene(256)
    assert radiance.shape[0] > ig.ANALYSIS_HEIGHT
    offsets = [[0.0, 0.0, -FLOOR + 0.2], [0.4, 0.0, -0.5]]
    fast = ig.irradiance_maps(radiance, distance, offsets, 32, DIFFUSE_LMAX_EXACT)
    monkeypatch.setattr(ig, "ANALYSIS_HEIGHT", 256)
    full = ig.irradiance_maps(radiance, distance, offsets, 32, DIFFUSE_LMAX_EXACT)
    np.testing.assert_allclose(fast, full, rtol=0.01, atol=1e-3)
