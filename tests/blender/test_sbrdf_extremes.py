"""White furnace (a white SBRDF in a constant environment renders the constant) and the
extremes of every parameter render finite pixels everywhere, silhouettes included."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import sbrdf_scene as sc
from platelight.addon.material.params import SBRDFParams

FURNACE = {
    "white_diffuse": dict(diffuse_albedo=(1, 1, 1), specular_albedo=(0, 0, 0),
                          fresnel_falloff=0.0, glossiness=0.0),
    # phi = 1 makes f = 1: rho_s' = g' = 1 whatever the direction, for every map blend.
    "white_specular_blend": dict(diffuse_albedo=(0, 0, 0), specular_albedo=(0.3, 0.3, 0.3),
                                 fresnel_falloff=1.0, glossiness=0.5),
    "white_mirror": dict(diffuse_albedo=(0, 0, 0), specular_albedo=(1, 1, 1),
                         fresnel_falloff=1.0, glossiness=1.0, cx=-0.3, cy=-1.0),
}
EXTREMES = {
    "phi_zero_n0": dict(fresnel_falloff=0.0, glossiness=0.0),
    "phi_zero_n1": dict(fresnel_falloff=0.0, glossiness=1.0, specular_albedo=(1, 1, 1)),
    "phi_tiny": dict(fresnel_falloff=1e-6, glossiness=0.5),
    "c_zero": dict(cx=0.0, cy=0.0, cz=0.0, glossiness=1.0),
    "peak_below": dict(cz=-10.0, cx=10.0, cy=-10.0, glossiness=0.8),
    "retro_half": dict(retro_reflection=0.5, glossiness=1.0),
    "ior_one": dict(alpha=0.0, ior=1.0, glossiness=1.0),
    "ior_max": dict(alpha=0.0, ior=4.0, dispersion=0.5, glossiness=0.0),
    "emission_huge": dict(emission_strength=1e6),
    "everything_max": dict(diffuse_albedo=(1, 1, 1), specular_albedo=(1, 1, 1), glossiness=1.0,
                           fresnel_falloff=1.0, tangent_rotation=6.2831853, retro_reflection=1.0),
}


def _render(bpy, tmp, cases, maps):
    from bl_ext.dev.platelight.node_groups import sbrdf_material as sm

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    sc.write_maps(tmp / "probe", maps)
    spheres, (cols, rows) = sc.setup_scene(bpy, len(cases), size=32)
    for ob, values in zip(spheres, cases.values()):
        ob.platelight.probe_dir = str(tmp / "probe")
        sm.apply_sbrdf_material(ob, params=dataclasses.replace(SBRDFParams(), **values))
    image = sc.render(bpy, tmp / "out.exr")
    size = image.shape[0] // rows
    tiles = {}
    for i, name in enumerate(cases):
        r, c = divmod(i, cols)
        tiles[name] = image[r * size:(r + 1) * size, c * size:(c + 1) * size]
    return tiles


def test_white_furnace(bpy_module, tmp_path):
    const = 0.75
    maps = {k: np.full(v.shape, const, np.float32) for k, v in sc.synthetic_maps().items()}
    tiles = _render(bpy_module, tmp_path, FURNACE, maps)
    for name, tile in tiles.items():
        covered = tile[..., 3] >= 0.9999
        assert covered.sum() > 300, name
        err = np.abs(tile[covered][:, :3] - const).max()
        assert err < 1e-5 * const, f"{name}: furnace error {err:.2e}"


def test_extremes_render_finite(bpy_module, tmp_path):
    tiles = _render(bpy_module, tmp_path, EXTREMES, sc.synthetic_maps())
    for name, tile in tiles.items():
        assert np.isfinite(tile).all(), f"{name}: non-finite pixels"
        covered = tile[..., 3] > 0
        assert covered.sum() > 300, name
        assert (tile[covered][:, :3] >= 0).all(), f"{name}: negative radiance"
