"""The probe group reads the view-dependent ladder as addon/ibl/view_lobe.py says.

Spheres shaded by the SBRDF bound to a probe folder holding the four (synthetic) maps, sunless maps,
the ladder's rungs (different synthetic images) and a bake record with a sun and a sunless ladder:
the render against the numpy reference (tests/sbrdf_reference.py with the rungs), pixel by pixel.
With Glossy Lobes "Phong", or a record whose ladder holds the sun the group adds, the same folder
renders the four maps' look-ups and never a rung."""
from __future__ import annotations

import json

import numpy as np
import pytest

import sbrdf_scene as sc
from platelight.addon.exr_io import write_exr
from platelight.addon.ibl import sun_lobe, view_lobe

BASE = dict(diffuse_albedo=(0.0, 0.0, 0.0), specular_albedo=(0.9, 0.8, 0.7), glossiness=0.6,
            fresnel_falloff=1e-4, emission_strength=0.0)
CASES = {
    "glossy": BASE,
    "sharp": dict(BASE, glossiness=0.75),                 # reads glossy3 head-on
    "rough": dict(BASE, glossiness=0.2, diffuse_albedo=(0.3, 0.4, 0.5), specular_albedo=(0.2, 0.2, 0.2)),
    "mirror": dict(BASE, glossiness=1.0),
    "brushed": dict(BASE, anisotropy=0.8, tangent_rotation=0.5, fresnel_falloff=0.1),
    "fresnel": dict(BASE, glossiness=0.4, fresnel_falloff=0.3, diffuse_albedo=(0.3, 0.2, 0.3),
                    specular_albedo=(0.05, 0.05, 0.05)),
}
SUN = sc.SUN


def _record(sunless_ladder):
    return json.dumps({"hash": "test", "maps": list(sc.MAP_HEIGHTS), sun_lobe.RECORD_KEY: sun_lobe.to_record(SUN),
                       view_lobe.RECORD_KEY: {"version": view_lobe.VERSION, "sunless": sunless_ladder}})


def _render(bpy, folder, lobes):
    return sc.render_cases_in_new_scene(bpy, folder, CASES, glossy_lobes=lobes)


@pytest.fixture(scope="module")
def rendered(bpy_module, tmp_path_factory):
    bpy = bpy_module
    folder = tmp_path_factory.mktemp("view_lobe") / "probe"
    maps, sunless = sc.write_sunlit_probe(folder)
    other = sc.synthetic_maps(seed=2)
    rungs = {"glossy1": other["glossy1"], "glossy2": other["glossy2"], view_lobe.GLOSSY3: other["specular"]}
    for name, image in rungs.items():
        write_exr(folder / view_lobe.rung_filename(name), image)
    (folder / "bake.json").write_text(_record(True))
    renders = {"view": _render(bpy, folder, view_lobe.MODE), "phong": _render(bpy, folder, "phong")}
    # a ladder that kept the sun, in a group that adds the sun: the four maps, never both
    (folder / "bake.json").write_text(_record(False))
    renders["mismatch"] = _render(bpy, folder, view_lobe.MODE)
    return dict(renders, maps=maps, sunless=sunless, rungs=rungs)


def _worst(rendered, key, case, rungs):
    return sc.worst_relative_error(rendered[key], rendered["maps"], CASES, case, sun=SUN,
                                   sunless=rendered["sunless"], rungs=rungs)


@pytest.mark.parametrize("case", list(CASES))
def test_the_ladder_matches_numpy_reference(rendered, case):
    worst = _worst(rendered, "view", case, rendered["rungs"])
    # Blender evaluates Float Curves (tilt, roughness, ladder position, albedo) from 256-entry tables
    assert worst < 2e-3, f"{case}: worst relative error {worst:.2e}"
    if case != "mirror":
        # the rungs show: the four maps' look-up is far from this render
        without = _worst(rendered, "view", case, None)
        assert without > 0.05, f"{case}: the render does not read the ladder ({without:.3f})"


@pytest.mark.parametrize("key", ["phong", "mismatch"])
@pytest.mark.parametrize("case", ["glossy", "sharp", "brushed"])
def test_without_the_ladder_the_four_maps_are_read(rendered, key, case):
    worst = _worst(rendered, key, case, None)
    assert worst < 2e-3, f"{key}, {case}: worst relative error {worst:.2e}"
