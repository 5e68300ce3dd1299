"""addon/material/self_occlusion.py against analytic cases, its rays cast here by brute force
(Möller-Trumbore over every triangle): a convex box hides none of its sky, its inside all of it,
and the inside of a box open at the top 4/5 (reciprocity: the opening, which sees only the five
inner faces, sends them 1/5 of their area-weighted view)."""
from __future__ import annotations

import numpy as np
import pytest

from platelight.addon.material.self_occlusion import (RAYS_PER_POINT, SAMPLE_POINTS, cosine_directions,
                                                      occluded_fraction, rays, surface_samples)

# the unit cube's faces as quads, wound counter-clockwise seen from outside
FACES = {"bottom": [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)], "top": [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
         "front": [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)], "back": [(0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)],
         "left": [(0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)], "right": [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)]}


def box(faces=FACES, inward=False):
    triangles = []
    for a, b, c, d in (FACES[name] for name in faces):
        triangles += [(a, b, c), (a, c, d)]
    triangles = np.array(triangles, float)
    return triangles[:, ::-1] if inward else triangles


def hits(triangles, origins, directions):
    """Does each ray (origins (N, 3), directions (N, R, 3)) meet any triangle, either side, ahead?"""
    o = np.repeat(origins, directions.shape[1], axis=0)
    d = directions.reshape(-1, 3)
    met = np.zeros(len(d), bool)
    for a, b, c in triangles:
        e1, e2 = b - a, c - a
        p = np.cross(d, e2)
        det = p @ e1
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", d, q) * inv
        t = (q @ e2) * inv
        met |= ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return met.reshape(directions.shape[:2])


def fraction_hidden(triangles):
    origins, directions = rays(triangles)
    return occluded_fraction(hits(triangles, origins, directions))


def test_a_convex_box_hides_none_of_its_sky_and_its_inside_all():
    assert fraction_hidden(box()) == 0.0
    assert fraction_hidden(box(inward=True)) == 1.0


def test_the_inside_of_a_box_open_at_the_top_hides_four_fifths():
    open_box = box([name for name in FACES if name != "top"], inward=True)
    # 8192 rays: the estimate's standard error is about 0.004
    assert fraction_hidden(open_box) == pytest.approx(0.8, abs=0.015)


def test_the_samples_are_uniform_over_the_area_and_the_directions_cosine_weighted():
    rng = np.random.default_rng(1)
    small = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]                     # area 1/2
    large = [(5, 0, 0), (8, 0, 0), (5, 1, 0)]                     # area 3/2
    points, normals = surface_samples(np.array([small, large], float), 20000, rng)
    assert np.mean(points[:, 0] >= 5) == pytest.approx(0.75, abs=0.01)
    np.testing.assert_allclose(normals, [[0, 0, 1]] * len(normals))
    tilted = np.array([[0.0, 0.6, 0.8]] * 2000)
    directions = cosine_directions(tilted, 16, rng)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, atol=1e-12)
    cosine = directions @ tilted[0]
    assert cosine.min() >= 0.0
    assert cosine.mean() == pytest.approx(2.0 / 3.0, abs=0.005)   # E[cos] under cos/pi is 2/3


def test_rays_start_above_the_surface_and_nothing_without_area_casts():
    origins, directions = rays(box())
    assert origins.shape == (SAMPLE_POINTS, 3) and directions.shape == (SAMPLE_POINTS, RAYS_PER_POINT, 3)
    outside = (origins < 0).any(axis=1) | (origins > 1).any(axis=1)
    assert outside.all()                                          # a hair off every face, outwards
    flat = np.zeros((2, 3, 3))
    origins, directions = rays(flat)
    assert origins.shape == (0, 3) and occluded_fraction(np.zeros((0, RAYS_PER_POINT), bool)) == 0.0
