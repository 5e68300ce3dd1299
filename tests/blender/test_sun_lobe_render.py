"""The probe group shades a baked sun through the lobe as addon/ibl/sun_lobe.py says.

Spheres shaded by the SBRDF bound to a probe folder holding the four (synthetic) maps, different
sunless maps and a bake record with a sun: the render against the numpy reference
(tests/sbrdf_reference.py with the sun), pixel by pixel. Then the same folder with the scene's Sun
Highlight off (and with a record without a sun) reads the four maps and no sun."""
from __future__ import annotations

import json

import numpy as np
import pytest

import sbrdf_scene as sc
from platelight.addon.exr_io import write_exr
from platelight.addon.ibl import sun_lobe

BASE = dict(diffuse_albedo=(0.0, 0.0, 0.0), specular_albedo=(0.9, 0.8, 0.7), glossiness=0.6,
            fresnel_falloff=1e-4, emission_strength=0.0)
CASES = {
    "glossy": BASE,
    "rough": dict(BASE, glossiness=0.2, diffuse_albedo=(0.3, 0.4, 0.5), specular_albedo=(0.2, 0.2, 0.2)),
    "rough_metal": dict(BASE, glossiness=0.1),
    # glossiness 0 with the peak pulled towards N: a converted roughness-0.85 lobe, its sun
    # through GGX of that roughness
    "pulled": dict(BASE, glossiness=0.0, cx=-0.4, cy=-0.4, fresnel_falloff=0.05),
    "near_mirror": dict(BASE, glossiness=0.85),
    "mirror": dict(BASE, glossiness=1.0),
    "brushed": dict(BASE, anisotropy=0.8, tangent_rotation=0.5, fresnel_falloff=0.1),
    "retro": dict(BASE, glossiness=0.7, retro_reflection=0.6),
    "fresnel": dict(BASE, glossiness=0.4, fresnel_falloff=0.3, diffuse_albedo=(0.3, 0.2, 0.3),
                    specular_albedo=(0.05, 0.05, 0.05)),
    "transparent": dict(BASE, glossiness=0.9, fresnel_falloff=1 / 6, alpha=0.3, ior=1.45,
                        diffuse_albedo=(0.9, 1.0, 0.8), specular_albedo=(0.04, 0.04, 0.04)),
}
SUN = sc.SUN


def _render(bpy, folder, sun_highlight):
    return sc.render_cases_in_new_scene(bpy, folder, CASES, probe_sun_lobe=sun_highlight)


@pytest.fixture(scope="module")
def rendered(bpy_module, tmp_path_factory):
    bpy = bpy_module
    folder = tmp_path_factory.mktemp("sun_lobe") / "probe"
    maps, sunless = sc.write_sunlit_probe(folder)
    (folder / "bake.json").write_text(json.dumps({"hash": "test", "maps": list(maps),
                                                  sun_lobe.RECORD_KEY: sun_lobe.to_record(SUN)}))
    renders = {"on": _render(bpy, folder, True), "off": _render(bpy, folder, False)}
    # a record without a sun (a bake that found none): the four maps, whatever the setting says
    (folder / "bake.json").write_text(json.dumps({"hash": "test", "maps": list(maps)}))
    renders["no sun"] = _render(bpy, folder, True)
    return dict(renders, maps=maps, sunless=sunless)


def _worst(rendered, key, case, sun, sunless):
    return sc.worst_relative_error(rendered[key], rendered["maps"], CASES, case, sun=sun, sunless=sunless)


@pytest.mark.parametrize("case", list(CASES))
def test_sun_through_the_lobe_matches_numpy_reference(rendered, case):
    worst = _worst(rendered, "on", case, SUN, rendered["sunless"])
    # 2e-3: Blender evaluates Float Curves (tilt, roughness, albedo) from 256-entry tables
    assert worst < 2e-3, f"{case}: worst relative error {worst:.2e}"
    if case != "mirror":
        # the sun shows: somewhere the highlight is most of the pixel
        without = _worst(rendered, "on", case, None, rendered["sunless"])
        assert without > 0.2, f"{case}: the sun's highlight is missing from the render ({without:.2f})"


@pytest.mark.parametrize("key", ["off", "no sun"])
@pytest.mark.parametrize("case", ["glossy", "brushed", "rough"])
def test_without_the_sun_the_maps_are_read(rendered, key, case):
    worst = _worst(rendered, key, case, None, None)
    assert worst < 2e-3, f"{key}, {case}: worst relative error {worst:.2e}"


def test_a_sequence_binds_its_sun_only_when_every_frame_has_the_same(bpy_module, tmp_path):
    """A frame-range bake: one sun for the group when every frame's record has it; a frame whose
    probe lost it (an object moved into shadow) makes the whole sequence read its four maps."""
    from bl_ext.dev.platelight.node_groups import probe_maps
    from platelight.addon import names

    bpy = bpy_module
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    maps = sc.synthetic_maps()
    for frame in (1, 2):
        sc.write_maps(tmp_path, maps, frame=frame)
        for name in sun_lobe.SUNLESS_MAPS:
            write_exr(tmp_path / sun_lobe.sunless_filename(name, frame), maps[name] * 0.5)
        (tmp_path / f"bake_{frame:04d}.json").write_text(json.dumps(
            {"hash": "x", "maps": list(maps), sun_lobe.RECORD_KEY: sun_lobe.to_record(SUN)}))
    group = probe_maps.ensure_probe_group(str(tmp_path))

    def bound():
        rgb = [group.nodes[names.SUN_COLOR_NODE].inputs[a].default_value for a in "XYZ"]
        image = next(n.image for n in group.nodes if n.get("platelight_map") == "glossy2_sunless")
        return rgb, image.filepath.rsplit("/", 1)[-1]
    rgb, image = bound()
    np.testing.assert_allclose(rgb, SUN.rgb, rtol=1e-6)
    assert image == "glossy2_sunless_0001.exr"
    (tmp_path / "bake_0002.json").write_text(json.dumps({"hash": "x", "maps": list(maps)}))
    probe_maps.bind_images(group)
    rgb, image = bound()
    assert rgb == [0.0, 0.0, 0.0] and image == "glossy2_0001.exr"
