"""apply_sbrdf, the binding to probe maps (single, sequence, missing), group versioning,
presets, Principled conversion and JSON export/import inside Blender."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import sbrdf_scene as sc
from platelight.addon import names
from platelight.addon.ibl.anisotropy import TAP_SLOPES
from platelight.addon.ibl.distance import DISTANCE_NAME
from platelight.addon.ibl import sun_lobe, view_lobe
from platelight.addon.ibl.irradiance_grid import GRID_NAME
from platelight.addon.material.params import PARAMETERS
from platelight.addon.material.presets import PRESETS, preset_label, preset_params
from support import compat


# what the parallax look-ups and the view-dependent ladder's glossy3 read beside the four maps
LOOKUP_FILES = (DISTANCE_NAME, GRID_NAME, view_lobe.GLOSSY3)


def _sm():
    from bl_ext.dev.platelight.node_groups import sbrdf_material
    return sbrdf_material


def _sphere(bpy, name="Ball"):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
    ob = bpy.context.object
    ob.name = name
    return ob


def _principled(bpy, name="Red"):
    mat = compat().new_material(name)
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (0.8, 0.1, 0.05, 1.0)
    node.inputs["Roughness"].default_value = 0.0
    node.inputs["Emission Strength"].default_value = 2.0
    return mat


def test_apply_sbrdf_converts_principled_and_binds_probe(bpy_clean, tmp_path):
    bpy = bpy_clean
    sc.write_maps(tmp_path / "probe", sc.synthetic_maps())
    ob = _sphere(bpy)
    old = _principled(bpy)
    ob.data.materials.append(old)
    ob.platelight.probe_dir = str(tmp_path / "probe")
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    mat = ob.active_material
    sm = _sm()
    node = sm.sbrdf_node(mat)
    assert node is not None and mat is not old
    assert old.use_fake_user and old.name in bpy.data.materials   # nothing lost
    params = sm.read_params(mat)
    assert params.diffuse_albedo == pytest.approx((0.8, 0.1, 0.05), abs=1e-6)
    assert params.glossiness == pytest.approx(1.0)
    assert params.emission_strength == pytest.approx(2.0)
    probe = sm.probe_node(mat).node_tree
    envs = [n for n in probe.nodes if n.bl_idname == "ShaderNodeTexEnvironment"
            and n.get("platelight_map") not in LOOKUP_FILES]     # the parallax look-ups have their own
    # the diffuse lobe's map + each anisotropic tap's three glossy/mirror maps + the specular
    # lobe's (sunless) diffuse map + three refraction channels' four maps
    expected = 1 + 3 * len(TAP_SLOPES) + 1 + 3 * 4
    assert len(envs) == expected and all(n.image is not None for n in envs)
    assert {n.image.name for n in envs} == {f"{m}.exr" for m in sc.MAP_HEIGHTS}
    assert all(n.interpolation == "Linear" for n in envs)
    surface = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    # camera rays see the probe's emission, every other ray the Principled twin (ray_twin.py)
    mix = surface.inputs["Surface"].links[0].from_node
    assert mix.name == "PlateLight Ray Mix" and mix.inputs[2].links[0].from_node == sm.probe_node(mat)
    twin = mix.inputs[1].links[0].from_node
    assert twin.bl_idname == "ShaderNodeBsdfPrincipled"
    assert tuple(twin.inputs["Base Color"].default_value[:3]) == pytest.approx((0.8, 0.1, 0.05), abs=1e-6)
    assert twin.inputs["Emission Strength"].default_value == 0.0   # the camera sees the SBRDF's
    # Applying again rebinds, never duplicates groups or materials.
    n_groups, n_mats = len(bpy.data.node_groups), len(bpy.data.materials)
    assert bpy.ops.platelight.apply_sbrdf(preset="chrome") == {"FINISHED"}
    assert (len(bpy.data.node_groups), len(bpy.data.materials)) == (n_groups, n_mats)
    assert sm.read_params(ob.active_material).specular_albedo == pytest.approx((0.9,) * 3)


def test_apply_sbrdf_poll_needs_an_object(bpy_clean):
    bpy = bpy_clean
    assert not bpy.ops.platelight.apply_sbrdf.poll()
    with pytest.raises(RuntimeError, match="Select a mesh"):
        bpy.ops.platelight.apply_sbrdf()


def test_a_nan_principled_value_is_refused_and_the_object_kept(bpy_clean, tmp_path):
    bpy = bpy_clean
    ob = _sphere(bpy)
    good, bad = _principled(bpy, "Good"), _principled(bpy, "Bad")
    node = next(n for n in bad.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Roughness"].default_value = float("nan")     # Blender stores it as it is
    ob.data.materials.append(good)
    ob.data.materials.append(bad)
    materials, groups = set(bpy.data.materials), set(bpy.data.node_groups)
    with pytest.raises(RuntimeError, match="Bad's Principled BSDF has Roughness set to NaN"):
        bpy.ops.platelight.apply_sbrdf()
    # the first slot, which could be converted, was not either: nothing half done
    assert [slot.material for slot in ob.material_slots] == [good, bad]
    assert set(bpy.data.materials) == materials and set(bpy.data.node_groups) == groups
    node.inputs["Roughness"].default_value = 0.5
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    assert all(_sm().sbrdf_node(slot.material) is not None for slot in ob.material_slots)


def test_missing_maps_fall_back_to_world_maps(bpy_clean, tmp_path):
    bpy = bpy_clean
    bpy.context.scene.platelight.maps_dir = str(tmp_path)
    sc.write_maps(tmp_path / "_world", sc.synthetic_maps(seed=3))
    ob = _sphere(bpy)
    ob.platelight.probe_dir = str(tmp_path / "not_baked")
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob)
    folder, status = sm.resolve_probe_dir(ob, bpy.context.scene)
    assert "using the world maps" in status
    assert mat["platelight_probe_dir"] == folder
    envs = [n for n in sm.probe_node(mat).node_tree.nodes
            if n.bl_idname == "ShaderNodeTexEnvironment" and n.get("platelight_map") not in LOOKUP_FILES]
    assert all(n.image is not None and "_world" in n.image.filepath for n in envs)
    # Once the object's own maps exist, a refresh/apply binds them.
    sc.write_maps(tmp_path / "not_baked", sc.synthetic_maps())
    mat = sm.apply_sbrdf_material(ob)
    assert mat["platelight_probe_dir"] == str(tmp_path / "not_baked")


def test_image_sequence_maps(bpy_clean, tmp_path):
    bpy = bpy_clean
    maps = sc.synthetic_maps()
    for frame in (1, 2, 3):
        sc.write_maps(tmp_path / "seq", {k: v * frame for k, v in maps.items()}, frame=frame)
    ob = _sphere(bpy)
    ob.platelight.probe_dir = str(tmp_path / "seq")
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob)
    envs = [n for n in sm.probe_node(mat).node_tree.nodes
            if n.bl_idname == "ShaderNodeTexEnvironment" and n.get("platelight_map") not in LOOKUP_FILES]
    assert all(n.image.source == "SEQUENCE" for n in envs)
    # frame F reads <map>_F.exr, independent of which frames existed when the material was bound
    assert all(n.image_user.frame_start == 1 and n.image_user.frame_offset == 0
               and n.image_user.frame_duration > 100000 and n.image_user.use_auto_refresh
               for n in envs)
    assert envs[0].image.filepath.endswith("_0001.exr")


def test_sequence_reads_the_ladder_only_when_every_frame_has_its_rungs(bpy_clean, tmp_path):
    """The ladder's switch is one for all frames: a frame baked without rungs (another Glossy
    Lobes, an older bake on a farm node) turns it off, so that no frame reads missing rungs."""
    from platelight.addon.bake.layout import write_record
    from platelight.addon.exr_io import write_exr

    folder = tmp_path / "seq"
    maps = sc.synthetic_maps()
    for frame in (1, 2, 3):
        sc.write_maps(folder, maps, frame=frame)
        for name in view_lobe.RUNGS:
            write_exr(folder / view_lobe.rung_filename(name, frame), maps["specular"])
        write_record(str(folder), frame, "test", list(maps), **{view_lobe.RECORD_KEY: {
            "version": view_lobe.VERSION, "sunless": False}})
    ob = _sphere(bpy_clean)
    ob.platelight.probe_dir = str(folder)
    sm = _sm()

    def ladder_on():
        group = sm.probe_node(sm.apply_sbrdf_material(ob)).node_tree
        return group.nodes[names.VIEW_LOBE_NODE].outputs[0].default_value == 1.0

    assert ladder_on()
    (folder / view_lobe.rung_filename("glossy2", 3)).unlink()
    assert not ladder_on()


def test_group_is_idempotent_and_upgrades_in_place(bpy_clean, tmp_path):
    bpy = bpy_clean
    from bl_ext.dev.platelight.node_groups import sbrdf

    ob = _sphere(bpy)
    ob.platelight.probe_dir = str(tmp_path)
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob, preset_name="plastic")
    group = bpy.data.node_groups[names.SBRDF_GROUP]
    assert sbrdf.ensure_sbrdf_group() == group
    assert [g.name for g in bpy.data.node_groups].count(names.SBRDF_GROUP) == 1
    labels = [i.name for i in group.interface.items_tree if i.in_out == "INPUT"]
    for name in ("Diffuse Albedo", "Specular Albedo", "Glossiness", "Cx", "Cy", "Cz",
                 "Fresnel Falloff", "Tangent Rotation", "Normal"):
        assert name in labels
    # An "old" group: older version, a node removed, a stale socket. Upgrading keeps the
    # material's values and links.
    group[sbrdf.VERSION_KEY] = 0
    group.nodes.remove(group.nodes[5])
    group.interface.new_socket("Obsolete", in_out="INPUT", socket_type="NodeSocketFloat")
    n_nodes = len(group.nodes)
    sbrdf.ensure_sbrdf_group()
    assert group[sbrdf.VERSION_KEY] == sbrdf.VERSION and len(group.nodes) == n_nodes + 1
    assert "Obsolete" not in [i.name for i in group.interface.items_tree]
    assert sm.read_params(mat).diffuse_albedo == pytest.approx(PRESETS["plastic"]["diffuse_albedo"])
    assert sm.probe_node(mat).inputs["Map Glossiness"].is_linked
    # A file from before an output was added (here the Lobe View): re-binding it after a bake
    # upgrades the SBRDF group and links the new output to the (rebuilt) probe group.
    group.interface.remove(next(i for i in group.interface.items_tree if i.name == "Lobe View"))
    group[sbrdf.VERSION_KEY] = 4
    sm.bind_probe(mat, str(tmp_path))
    assert group[sbrdf.VERSION_KEY] == sbrdf.VERSION and sm.probe_node(mat).inputs["Lobe View"].is_linked


def _upgraded_from(bpy, tmp_path, preset, version, missing):
    """A material with ``preset`` on a group made as ``version``, before its ``missing`` input
    existed, upgraded to the current group."""
    from bl_ext.dev.platelight.node_groups import sbrdf

    ob = _sphere(bpy)
    ob.platelight.probe_dir = str(tmp_path)
    material = _sm().apply_sbrdf_material(ob, preset_name=preset)
    group = bpy.data.node_groups[names.SBRDF_GROUP]
    group[sbrdf.VERSION_KEY] = version
    group.interface.remove(next(i for i in group.interface.items_tree if i.name == missing))
    assert missing not in _sm().sbrdf_node(material).inputs
    sbrdf.ensure_sbrdf_group()
    return material


def test_version_1_groups_keep_the_papers_falloff(bpy_clean, tmp_path):
    """Materials made before the Paper Falloff input rendered with the paper's g': the upgrade
    keeps that (1) on them, while new materials get the default (0)."""
    bpy = bpy_clean
    sm = _sm()
    old = _upgraded_from(bpy, tmp_path, "chrome", 1, "Paper Falloff")
    assert sm.read_params(old).paper_falloff == 1.0
    new = sm.apply_sbrdf_material(_sphere(bpy), preset_name="chrome")
    assert new != old and sm.read_params(new).paper_falloff == 0.0


def test_groups_before_fresnel_peak_keep_the_papers_fresnel(bpy_clean, tmp_path):
    """A material made before the Fresnel Peak input (group version 5) keeps the paper's f, which
    reaches 1 at grazing; a rough Principled plastic converted now reaches GGX's 18 %."""
    bpy = bpy_clean
    sm = _sm()
    old = _upgraded_from(bpy, tmp_path, "plastic", 5, "Fresnel Peak")
    assert sm.read_params(old).fresnel_peak == 1.0
    plastic = _principled(bpy, "Plastic")
    next(n for n in plastic.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled").inputs["Roughness"].default_value = 0.5
    other = _sphere(bpy, "Other")
    other.data.materials.append(plastic)
    converted = sm.apply_sbrdf_material(other)
    assert sm.read_params(converted).fresnel_peak == pytest.approx(0.181, abs=1e-3)


def test_socket_limits_match_parameter_ranges(bpy_clean):
    from bl_ext.dev.platelight.node_groups import sbrdf

    group = sbrdf.ensure_sbrdf_group()
    items = {i.name: i for i in group.interface.items_tree if i.in_out == "INPUT"}
    for spec in PARAMETERS:
        if spec.kind == "float":
            assert items[spec.label].min_value == pytest.approx(spec.minimum)
            assert items[spec.label].max_value == pytest.approx(spec.maximum)


def test_builtin_preset_files_match_presets(bpy_clean, tmp_path):
    bpy = bpy_clean
    import os
    from bl_ext.dev.platelight.operators.material import BUILTIN_PRESETS

    ob = _sphere(bpy)
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob)
    for name in PRESETS:
        path = os.path.join(BUILTIN_PRESETS, preset_label(name) + ".py")
        with bpy.context.temp_override(material=mat):
            assert bpy.ops.script.execute_preset(
                filepath=path, menu_idname="PLATELIGHT_MT_sbrdf_presets") == {"FINISHED"}
        _close(sm.read_params(mat), preset_params(name))
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.platelight.sbrdf_preset(preset="glass") == {"FINISHED"}
    assert sm.read_params(mat).alpha == 0.0


def _close(a, b):
    for spec in PARAMETERS:
        assert np.allclose(getattr(a, spec.name), getattr(b, spec.name), atol=1e-6), spec.name
    return True


def test_json_export_import_and_bad_files(bpy_clean, tmp_path):
    bpy = bpy_clean
    ob = _sphere(bpy)
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob, preset_name="brushed_metal")
    path = tmp_path / "brushed.json"
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.platelight.sbrdf_export(filepath=str(path)) == {"FINISHED"}
    data = json.loads(path.read_text())
    assert data["format"] == "platelight-sbrdf" and data["parameters"]["cy"] == pytest.approx(-0.25)
    sm.write_params(mat, preset_params("rubber"))
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.platelight.sbrdf_import(filepath=str(path)) == {"FINISHED"}
    _close(sm.read_params(mat), preset_params("brushed_metal"))
    # Malformed and unknown-version files: a clear error, nothing changed.
    bad = tmp_path / "bad.json"
    for text in ("{not json", json.dumps(dict(data, version=99)),
                 json.dumps(dict(data, parameters={"glossiness": "high"}))):
        bad.write_text(text)
        before = sm.read_params(mat)
        with bpy.context.temp_override(material=mat):
            with pytest.raises(RuntimeError, match="JSON|version 99|must be a number"):
                bpy.ops.platelight.sbrdf_import(filepath=str(bad))
        _close(sm.read_params(mat), before)


def test_convert_to_principled_and_back(bpy_clean, tmp_path):
    bpy = bpy_clean
    ob = _sphere(bpy)
    sm = _sm()
    sm.apply_sbrdf_material(ob, preset_name="chrome")
    sbrdf_mat = ob.active_material
    assert bpy.ops.platelight.sbrdf_to_principled() == {"FINISHED"}
    mat = ob.active_material
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert node.inputs["Metallic"].default_value == 1.0
    assert node.inputs["Roughness"].default_value == pytest.approx(0.0, abs=1e-6)
    assert sbrdf_mat.use_fake_user
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    back = sm.read_params(ob.active_material)
    assert back.specular_albedo == pytest.approx((0.9, 0.9, 0.9), abs=1e-6)
    assert back.glossiness == pytest.approx(1.0)


def test_render_preset_row_leaves_the_scene_alone(bpy_clean, tmp_path):
    bpy = bpy_clean
    from bl_ext.dev.platelight.node_groups.sbrdf_preview import render_preset_row

    import glob
    import tempfile

    ob = _sphere(bpy, "UserObject")
    leftovers = set(glob.glob(f"{tempfile.gettempdir()}/platelight-presets-*"))
    before = (len(bpy.data.scenes), sorted(o.name for o in bpy.data.objects),
              len(bpy.data.materials), bpy.context.scene.name)
    out = render_preset_row(str(tmp_path / "row.png"), presets=["chrome", "plastic", "emissive"],
                            sphere_px=24, samples=1)
    after = (len(bpy.data.scenes), sorted(o.name for o in bpy.data.objects),
             len(bpy.data.materials), bpy.context.scene.name)
    assert before == after and ob.name in bpy.data.objects
    # its temporary maps are gone, with the probe group and images that read them
    assert set(glob.glob(f"{tempfile.gettempdir()}/platelight-presets-*")) <= leftovers
    assert not any("platelight-presets-" in im.filepath for im in bpy.data.images)
    assert not any(g.get("platelight_probe_dir", "").find("platelight-presets-") >= 0
                   for g in bpy.data.node_groups)
    image = bpy.data.images.load(out)
    assert tuple(image.size) == (72, 24)
    px = np.array(image.pixels[:]).reshape(24, 72, 4)[..., :3]
    centres = [px[12, 12 + 24 * i] for i in range(3)]
    assert centres[1][0] > 2 * centres[1][2]          # plastic is red
    assert centres[2].min() > 0.8                      # emissive is bright
    assert not np.allclose(centres[0], centres[1], atol=0.05)


def test_user_preset_through_blenders_preset_system(bpy_clean):
    bpy = bpy_clean
    import os

    assert hasattr(bpy.types, "PLATELIGHT_PT_material")
    ob = _sphere(bpy)
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob, preset_name="marble")
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.platelight.sbrdf_preset_add(name="My Marble") == {"FINISHED"}
    path = next(os.path.join(d, "My_Marble.py") for d in bpy.utils.preset_paths("platelight_sbrdf")
                if os.path.isfile(os.path.join(d, "My_Marble.py")))
    sm.write_params(mat, preset_params("chrome"))
    with bpy.context.temp_override(material=mat):
        bpy.ops.script.execute_preset(filepath=path, menu_idname="PLATELIGHT_MT_sbrdf_presets")
    _close(sm.read_params(mat), preset_params("marble"))


def test_group_interface_order(bpy_clean):
    from bl_ext.dev.platelight.node_groups import sbrdf

    group = sbrdf.ensure_sbrdf_group()
    inputs = [i.name for i in group.interface.items_tree if i.in_out == "INPUT"]
    assert inputs == [spec.label for spec in PARAMETERS] + ["Normal"]
    outputs = [i.name for i in group.interface.items_tree if i.in_out == "OUTPUT"]
    assert outputs == [n for n, _ in sbrdf.LOOKUP_SOCKETS + sbrdf.DEBUG_SOCKETS]


class _Layout:
    """Records what a panel draws (headless Blender has no UI to draw into)."""

    def __init__(self, log):
        self.log = log
        self.use_property_split = False
        self.active = True

    def _child(self, *args, **kwargs):
        return _Layout(self.log)

    row = column = _child

    def label(self, text="", icon="NONE"):
        self.log.append(("label", text))

    def prop(self, data, prop, text=""):
        getattr(data, prop)                     # the property must exist
        self.log.append(("prop", text))

    def operator(self, idname, text="", icon="NONE"):
        self.log.append(("operator", idname))
        return type("Props", (), {})()

    def menu(self, idname, text=""):
        self.log.append(("menu", idname))

    def template_preview(self, material):
        self.log.append(("preview", material.name))


def test_material_panel_draws(bpy_clean, tmp_path):
    import types

    bpy = bpy_clean
    panel = bpy.types.PLATELIGHT_PT_material
    ob = _sphere(bpy)
    ob.data.materials.append(_principled(bpy))
    log = []
    context = types.SimpleNamespace(object=ob, material=ob.active_material)
    panel.draw(types.SimpleNamespace(layout=_Layout(log)), context)
    assert ("operator", "platelight.apply_sbrdf") in log

    ob.platelight.probe_dir = str(tmp_path / "missing")
    mat = _sm().apply_sbrdf_material(ob)
    log.clear()
    context = types.SimpleNamespace(object=ob, material=mat)
    panel.draw(types.SimpleNamespace(layout=_Layout(log)), context)
    drawn = [text for kind, text in log if kind == "prop"]
    assert sorted(drawn) == sorted(spec.label for spec in PARAMETERS)
    assert any(kind == "label" and "Maps missing" in text for kind, text in log)
    assert ("menu", "PLATELIGHT_MT_sbrdf_presets") in log


def test_a_partial_bake_binds_the_maps_it_has(bpy_clean, tmp_path):
    """The bake writes only the maps an object's materials read (issue 4): a folder holding
    diffuse alone is the object's probe, not a reason to fall back to the world's maps."""
    bpy = bpy_clean
    bpy.context.scene.platelight.maps_dir = str(tmp_path)
    sc.write_maps(tmp_path / "_world", sc.synthetic_maps(seed=3))
    maps = sc.synthetic_maps()
    sc.write_maps(tmp_path / "matte", {"diffuse": maps["diffuse"]})
    ob = _sphere(bpy)
    ob.platelight.probe_dir = str(tmp_path / "matte")
    sm = _sm()
    mat = sm.apply_sbrdf_material(ob)
    assert mat["platelight_probe_dir"] == str(tmp_path / "matte")
    envs = [n for n in sm.probe_node(mat).node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]
    # without a sun, a sunless look-up reads its map itself
    diffuse = ("diffuse", sun_lobe.sunless_name("diffuse"))
    bound = {n["platelight_map"] for n in envs if n.image.name != "PlateLight Unbaked Map"}
    assert bound == set(diffuse)
    assert all("matte" in n.image.filepath and n.image.name == "diffuse.exr"
               for n in envs if n["platelight_map"] in diffuse)
    # the others read the generated black stand-in: no file for Cycles to miss
    assert all(n.image.source == "GENERATED" for n in envs if n["platelight_map"] not in diffuse)
