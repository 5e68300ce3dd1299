"""The look-up tilt (addon/ibl/lobe_tilt.py): its table against brute force, and what it buys."""
from __future__ import annotations

import numpy as np
import pytest

import reference
import support  # noqa: F401
from platelight.addon.ibl import equirect as eq
from platelight.addon.ibl import lobe_tilt, maps
from platelight.addon.material.principled import roughness_to_glossiness


@pytest.mark.parametrize("name", ["diffuse", "glossy1", "glossy2"])
def test_rows_follow_the_brute_force_centroid(name):
    roughness = maps.MAP_ROUGHNESS[name]
    found = [lobe_tilt.halfway_offset(roughness, mu, height=384) for mu in lobe_tilt.MU]
    assert found == pytest.approx(lobe_tilt.TILT[name], abs=0.01)
    # the tilt grows towards grazing views and with roughness
    assert np.all(np.diff(lobe_tilt.TILT[name]) <= 0)


def test_kept_lobe_centroid_lies_between_r_and_n():
    mu = 0.2
    centroid = lobe_tilt.kept_lobe_centroid(0.45, mu)
    assert centroid[1] == pytest.approx(0.0, abs=1e-9)            # in the plane of N and R
    assert mu < centroid[2] < 1.0                                  # above R, below N
    # a polished lobe hardly reaches the horizon: its centroid is R
    assert lobe_tilt.kept_lobe_centroid(0.05, 0.5)[2] == pytest.approx(0.5, abs=1e-3)


def test_a_mirror_and_a_head_on_view_keep_r():
    assert lobe_tilt.tilt_offset(1.0, np.linspace(0, 1, 11)) == pytest.approx(0.0)
    n = np.array([[0.0, 0.0, 1.0]])
    assert lobe_tilt.tilted(n, n, 0.3) == pytest.approx(n)
    grazing = np.array([[np.sqrt(1 - 0.1 ** 2), 0.0, 0.1]])
    assert lobe_tilt.tilted(grazing, n, 0.3)[0, 2] > 0.1 + 0.1        # tilted towards N


def test_the_tilt_brings_a_rough_metal_sphere_nearer_brute_force_ggx():
    """A roughness-0.45 metal sphere (no Fresnel: the lobe alone) under a sky brighter above than
    below: the four maps looked up along R are darker than GGX towards its rim; tilted, nearer."""
    env = reference.sky_with_sun(64, 50.0)                      # a small bright light up the sky
    found = maps.compute_maps(env, maps.MapSettings()).maps
    view = np.array([1.0, 0.0, 0.0])
    normals = reference.sphere_facing_x()
    roughness = 0.45
    alpha = roughness ** 2
    truth = reference.anisotropic_ggx(env, alpha, alpha, normals, reference.tangents_about_z(normals),
                                      view, 64)
    glossiness = roughness_to_glossiness(roughness)
    reflected = 2 * (normals @ view)[:, None] * normals - view

    def error(directions):
        return float(np.sqrt(np.mean((maps.blended_lookup(found, glossiness, directions) - truth) ** 2)))

    plain, tilted = error(reflected), error(lobe_tilt.tilted(reflected, normals, glossiness))
    assert tilted < 0.6 * plain, (plain, tilted)
