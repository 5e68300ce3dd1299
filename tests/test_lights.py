"""Probe -> directional lights: energy kept exactly, the sun found where it is, irradiance against
a brute-force sum over every texel, bad input."""
import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.errors import PlateLightError
from platelight.addon.exr_io import read_exr
from platelight.addon.ibl import lights as L
from platelight.addon.ibl.equirect import dir_to_uv, downsample_area, texel_directions, texel_solid_angles


def total_energy(env):
    h, w = env.shape[:2]
    return (np.asarray(env, np.float64) * texel_solid_angles(h, w)[..., None]).sum(axis=(0, 1))


def sky_with_sun(direction, radius_deg=0.5, sun=5.0e4, sky=(0.4, 0.5, 0.8), height=256):
    """A constant sky with a disc sun of the given radius around ``direction``."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    dirs = texel_directions(height, 2 * height)
    env = np.empty((height, 2 * height, 3))
    env[:] = sky
    disc = dirs @ direction > np.cos(np.radians(radius_deg))
    env[disc] = sun * np.array([1.0, 0.9, 0.7])
    return env.astype(np.float32), disc


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


@pytest.mark.parametrize("name", ["sunrise", "courtyard"])
def test_lights_keep_the_probe_energy_exactly(studio_hdris, name):
    env = np.maximum(read_exr(studio_hdris[name]), 0)
    lights = L.probe_lights(env, 16)
    assert 16 <= len(lights) <= 17
    np.testing.assert_allclose(sum(light.rgb for light in lights), total_energy(env), rtol=1e-6)
    for light in lights:
        assert abs(np.linalg.norm(light.direction) - 1) < 1e-9
        assert np.all(light.rgb >= 0)


@pytest.mark.parametrize("direction", [(0.6, -0.3, 0.5), (-1.0, 0.001, 0.3), (0.1, 0.2, 0.97)])
def test_sun_found_in_its_direction(direction):
    # (-1, 0, .3) puts the sun on the u = 0/1 seam of the map: it must still be one sun
    env, disc = sky_with_sun(direction)
    found = L.find_sun(env)
    assert found is not None
    sun, blob = found
    assert angle_deg(sun.direction, direction) < 0.3
    h, w = env.shape[:2]
    disc_energy = (env[disc] * texel_solid_angles(h, w)[disc][:, None]).sum(axis=0)
    np.testing.assert_allclose(sun.rgb, disc_energy, rtol=1e-6)
    assert blob.sum() == disc.sum()
    assert np.degrees(sun.angle) < 3.0  # small: a sharp shadow


def test_sun_light_removes_the_sun_but_keeps_the_energy():
    env, disc = sky_with_sun((0.3, 0.4, 0.6))
    lights = L.probe_lights(env, 8)
    assert lights[0].is_sun and not any(light.is_sun for light in lights[1:])
    np.testing.assert_allclose(sum(light.rgb for light in lights), total_energy(env), rtol=1e-6)
    # the sky's lights carry only about the sky's energy (the sun's texels were filled with sky)
    sky_energy = np.array([0.4, 0.5, 0.8]) * 4 * np.pi
    np.testing.assert_allclose(sum(light.rgb for light in lights[1:]), sky_energy, rtol=1e-3)


def test_no_sun_in_an_overcast_or_broad_probe(studio_hdris):
    assert L.find_sun(np.full((32, 64, 3), 1.0, np.float32)) is None
    # courtyard's brightest area is a broad patch of sky (~35 degrees), not a sun
    assert L.find_sun(read_exr(studio_hdris["courtyard"])) is None


@pytest.mark.parametrize("name", ["sunrise", "studio"])
def test_irradiance_converges_to_brute_force(studio_hdris, name):
    """Independent reference: E(N) = Σ over every texel of L·max(0, N·ω)·dΩ."""
    env = downsample_area(np.maximum(read_exr(studio_hdris[name]), 0), 128).astype(np.float64)
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(100, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    dirs = texel_directions(128, 256).reshape(-1, 3)
    weights = texel_solid_angles(128, 256).reshape(-1)
    exact = (np.maximum(normals @ dirs.T, 0) * weights) @ env.reshape(-1, 3)
    errors = {}
    for count in (4, 16, 64):
        approx = L.irradiance(L.probe_lights(env, count), normals)
        errors[count] = np.abs(approx - exact).max() / exact.max()
    assert errors[64] < 0.02
    assert errors[64] < errors[16] < errors[4]


def test_median_cut_regions_share_the_energy():
    # a smooth sky brighter towards the top: 16 lights of about equal energy
    dirs = texel_directions(64, 128)
    env = np.repeat((1.0 + 3.0 * np.maximum(dirs[..., 2:3], 0)), 3, axis=2)
    lights = L.median_cut(env, 16)
    strengths = np.array([light.strength for light in lights])
    assert len(lights) == 16
    assert strengths.max() / strengths.min() < 2.5
    # more lights where the sky is brighter
    assert np.mean([light.direction[2] > 0 for light in lights]) > 0.5


def test_single_light_points_at_a_lone_bright_region():
    env, _ = sky_with_sun((0.0, 1.0, 0.2), radius_deg=3.0, sky=(0, 0, 0), height=64)
    light = L.median_cut(env, 1)[0]
    assert angle_deg(light.direction, (0.0, 1.0, 0.2)) < 1.0
    u, v = dir_to_uv(light.direction)
    assert abs(u - 0.25) < 0.01  # +Y at u = 0.25 (design.md)


def test_bad_input():
    with pytest.raises(PlateLightError, match="twice as wide"):
        L.probe_lights(np.ones((32, 32, 3), np.float32))
    with pytest.raises(PlateLightError, match="number of lights"):
        L.median_cut(np.ones((32, 64, 3), np.float32), 0)
    env = np.ones((32, 64, 3), np.float32)
    env[3, 4] = np.nan
    env[5, 6] = -np.inf
    lights = L.probe_lights(env, 4)
    assert all(np.all(np.isfinite(light.rgb)) for light in lights)


def test_split_sun_keeps_energy_and_leaves_a_sunless_sky():
    env, disc = sky_with_sun((0.2, -0.5, 0.6))
    sun, sky = L.split_sun(env)
    assert sun.is_sun
    h, w = env.shape[:2]
    np.testing.assert_allclose(sun.rgb + total_energy(sky), total_energy(env), rtol=1e-6)
    assert sky.max() < 1.0  # no sun left in the sky
    unchanged = ~disc
    np.testing.assert_array_equal(sky[unchanged], env[unchanged])
    assert L.split_sun(np.ones((16, 32, 3), np.float32))[0] is None
