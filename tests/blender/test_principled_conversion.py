"""Textured Principled materials keep their textures through Apply SBRDF.

The conversion group (node_groups/principled_conversion.py) must compute what
principled_to_sbrdf() computes in numpy, rendered exactly (emission, one sample, no filter);
and a sphere whose Principled inputs come from a node chain must render, on each side of the
chain's split, as the constant material of that side converted in numpy."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import sbrdf_scene as sc
from platelight.addon import names
from platelight.addon.material import principled as pr
from platelight.addon.material.params import SPEC
from support import compat

# Each rendered tile shows three outputs as RGB, mapped into [0, 1] where a value may leave it.
TRIPLES = (
    ("diffuse_albedo",), ("specular_albedo",), ("emission_color",),
    (("glossiness", 0.0, 1.0), ("cx", 1.0, 1.0), ("fresnel_falloff", 0.0, 1.0)),
    (("fresnel_peak", 0.0, 1.0), ("tangent_rotation", 0.0, 1 / (2 * math.pi)), ("anisotropy", 0.0, 1.0)),
    (("emission_strength", 0.0, 0.1), ("alpha", 0.0, 1.0), ("ior", -1.0, 1 / 3)),
    (("cy", 1.0, 1.0),),
)
CASES = (
    pr.PrincipledValues(),
    pr.PrincipledValues(base_color=(0.9, 0.6, 0.2), metallic=1.0, roughness=0.3),
    pr.PrincipledValues(base_color=(0.1, 0.7, 0.4), metallic=0.4, roughness=0.75, ior=1.33,
                        specular_ior_level=0.8, transmission=0.6, alpha=0.7, anisotropic=0.5,
                        anisotropic_rotation=1.3, emission_color=(0.2, 0.4, 1.0), emission_strength=4.0),
    pr.PrincipledValues(base_color=(1.0, 1.0, 1.0), metallic=1.0, roughness=1.0, ior=4.5,
                        specular_ior_level=1.0, anisotropic_rotation=-0.2),
    pr.PrincipledValues(base_color=(0.3, 0.3, 0.3), roughness=0.05, ior=2.4, specular_ior_level=0.3,
                        alpha=0.4, emission_strength=0.5),
    pr.PrincipledValues(base_color=(0.5, 0.2, 0.8), metallic=0.7, roughness=0.55),
)


def _conv():
    from bl_ext.dev.platelight.node_groups import principled_conversion
    return principled_conversion


def _sm():
    from bl_ext.dev.platelight.node_groups import sbrdf_material
    return sbrdf_material


def _tile_material(bpy, values, triple):
    """Emission showing ``triple`` of the conversion group's outputs for inputs ``values``."""
    from bl_ext.dev.platelight.node_groups.principled_nodes import SOCKETS

    mat = compat().new_material("Tile")
    tree = mat.node_tree
    tree.nodes.clear()
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = _conv().ensure_conversion_group()
    for field, socket in SOCKETS.items():
        value = getattr(values, field)
        group.inputs[socket].default_value = (*value, 1.0) if field.endswith("color") else value
    emission = tree.nodes.new("ShaderNodeEmission")
    if isinstance(triple[0], str):
        tree.links.new(group.outputs[SPEC[triple[0]].label], emission.inputs["Color"])
    else:
        combine = tree.nodes.new("ShaderNodeCombineXYZ")
        for index, (name, offset, scale) in enumerate(triple):
            mapped = tree.nodes.new("ShaderNodeMath")
            mapped.operation = "MULTIPLY"
            add = tree.nodes.new("ShaderNodeMath")
            add.operation = "ADD"
            tree.links.new(group.outputs[SPEC[name].label], add.inputs[0])
            add.inputs[1].default_value = offset
            tree.links.new(add.outputs[0], mapped.inputs[0])
            mapped.inputs[1].default_value = scale
            tree.links.new(mapped.outputs[0], combine.inputs[index])
        tree.links.new(combine.outputs[0], emission.inputs["Color"])
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(emission.outputs[0], out.inputs["Surface"])
    return mat


def _expected(values, triple):
    s = dataclasses.asdict(pr.principled_to_sbrdf(values))
    if isinstance(triple[0], str):
        return np.asarray(s[triple[0]], dtype=float)
    got = [(s[name] + offset) * scale for name, offset, scale in triple]
    return np.asarray(got + [0.0] * (3 - len(got)))


def _tiles(image, cols, size, count):
    for index in range(count):
        r, c = divmod(index, cols)
        tile = image[r * size:(r + 1) * size, c * size:(c + 1) * size]
        yield tile[..., :3].astype(np.float64), sc.interior_mask(tile[..., 3])


def test_conversion_group_computes_principled_to_sbrdf(bpy_clean, tmp_path):
    bpy = bpy_clean
    jobs = [(values, triple) for values in CASES for triple in TRIPLES]
    spheres, (cols, _rows) = sc.setup_scene(bpy, len(jobs), size=16)
    for ob, (values, triple) in zip(spheres, jobs):
        ob.data.materials.append(_tile_material(bpy, values, triple))
    image = sc.render(bpy, tmp_path / "conversion.exr")
    for (values, triple), (tile, mask) in zip(jobs, _tiles(image, cols, 16, len(jobs))):
        assert mask.sum() > 20
        got = tile[mask]
        assert np.ptp(got, axis=0).max() < 1e-6          # one value over the whole sphere
        want = _expected(values, triple)
        # 1e-3 (measured 2.5e-4): Blender evaluates the knot tables from 256-entry tables
        assert got.mean(axis=0) == pytest.approx(want, abs=1e-3), (values, triple)


def _split_material(bpy, top: pr.PrincipledValues, bottom: pr.PrincipledValues):
    """A Principled material whose Base Color, Metallic and Roughness come from a node chain:
    ``top``'s above the object's equator, ``bottom``'s below."""
    mat = compat().new_material("Split")
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    above = tree.nodes.new("ShaderNodeMath")
    above.operation = "GREATER_THAN"
    above.inputs[1].default_value = 0.0
    tree.links.new(coords.outputs["Object"], separate.inputs[0])
    tree.links.new(separate.outputs["Z"], above.inputs[0])
    for field, socket in (("base_color", "Base Color"), ("metallic", "Metallic"),
                          ("roughness", "Roughness")):
        kind = "RGBA" if field == "base_color" else "FLOAT"
        mix = tree.nodes.new("ShaderNodeMix")
        mix.data_type = kind
        inputs = [s for s in mix.inputs if s.enabled]
        tree.links.new(above.outputs[0], inputs[0])
        for slot, values in ((inputs[1], bottom), (inputs[2], top)):
            value = getattr(values, field)
            slot.default_value = (*value, 1.0) if kind == "RGBA" else value
        tree.links.new(next(s for s in mix.outputs if s.enabled), bsdf.inputs[socket])
    return mat


def _constant_material(values, name):
    from bl_ext.dev.platelight.node_groups.principled_nodes import build_principled_material
    return build_principled_material(name, values)


def test_a_textured_principled_renders_as_its_converted_constants(bpy_clean, tmp_path):
    """Sphere 0: the split material converted by Apply SBRDF; spheres 1 and 2: its top's and
    its bottom's constants converted in numpy. Same probe, same view: each half of sphere 0 must
    match its constant sphere, and the other rays must meet the textured Principled twin."""
    bpy = bpy_clean
    top = pr.PrincipledValues(base_color=(0.9, 0.6, 0.3), metallic=1.0, roughness=0.25)
    bottom = pr.PrincipledValues(base_color=(0.2, 0.5, 0.8), metallic=0.0, roughness=0.8)
    sc.write_maps(tmp_path / "probe", sc.synthetic_maps())
    spheres, (cols, _rows) = sc.setup_scene(bpy, 3, size=48)
    split = _split_material(bpy, top, bottom)
    for ob, mat in zip(spheres, (split, _constant_material(top, "Top"),
                                 _constant_material(bottom, "Bottom"))):
        ob.data.materials.append(mat)
        ob.platelight.probe_dir = str(tmp_path / "probe")
        _sm().apply_sbrdf_material(ob)
    converted = spheres[0].active_material
    tree = converted.node_tree
    sbrdf = _sm().sbrdf_node(converted)
    driven = {label for label, socket in sbrdf.inputs.items() if socket.is_linked}
    carried = {SPEC[name].label for field in ("base_color", "metallic", "roughness")
               for name in pr.CHANGES[field]}
    assert driven == carried                   # the editor keeps every other slider
    twin = tree.nodes[names.TWIN_NODE]
    assert twin.inputs["Base Color"].is_linked and twin.inputs["Roughness"].is_linked
    assert split.use_fake_user and split.name in bpy.data.materials     # the original kept
    assert not split.node_tree.nodes.get(names.PRINCIPLED_CONVERSION)

    rows = np.arange(48)[:, None] + 0.5 - 24.0        # pixel row from the tile's centre
    band = np.abs(rows) > 0.15 * 48 / 2.2             # away from the split at the equator
    scene = bpy.context.scene
    for engine in ("CYCLES", compat().EEVEE):           # the group compiles for the GPU too
        scene.render.engine = engine
        scene.eevee.taa_render_samples = 1
        scene.render.filter_size = 0.01
        tiles = list(_tiles(sc.render(bpy, tmp_path / f"split_{engine}.exr"), cols, 48, 3))
        for half, other in ((rows < 0, tiles[1]), (rows > 0, tiles[2])):
            mask = tiles[0][1] & other[1] & half & band
            assert mask.sum() > 300
            got, want = tiles[0][0][mask], other[0][mask]
            # measured 1.2e-5 in Cycles; EEVEE 8e-4, about one step of its half-float buffer
            tolerance = 1e-3 if engine == "CYCLES" else 3e-3
            assert np.abs(got - want).max() <= tolerance * max(want.max(), 0.05), engine


def test_apply_sbrdf_carries_textures_normal_maps_and_says_so(bpy_clean, capfd):
    """Through the operator: a texture on Base Color drives the conversion group, a Normal Map
    node the SBRDF's Normal, a texture on Emission Strength the SBRDF's emission but not the
    twin's (the camera would see it twice); the report names what was carried."""
    bpy = bpy_clean
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
    ob = bpy.context.object
    mat = compat().new_material("Painted")
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    links = {"Base Color": ("ShaderNodeTexChecker", "Color"),
             "Normal": ("ShaderNodeNormalMap", "Normal"),
             "Emission Strength": ("ShaderNodeTexNoise", "Fac")}
    for socket, (idname, output) in links.items():
        tree.links.new(tree.nodes.new(idname).outputs[output], bsdf.inputs[socket])
    from bl_ext.dev.platelight.node_groups.principled_nodes import linked_inputs
    assert linked_inputs(mat) == ["Base Color", "Emission Strength", "Normal"]
    ob.data.materials.append(mat)
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    printed = capfd.readouterr()          # Blender prints a background operator's reports
    assert "Painted's Base Color, Emission Strength, Normal came from links (textures, node " \
        "chains): carried" in printed.out + printed.err
    converted = ob.active_material
    sbrdf = _sm().sbrdf_node(converted)
    conversion = converted.node_tree.nodes[names.PRINCIPLED_CONVERSION]
    assert conversion.inputs["Base Color"].links[0].from_node.bl_idname == "ShaderNodeTexChecker"
    assert sbrdf.inputs["Normal"].links[0].from_node.bl_idname == "ShaderNodeNormalMap"
    assert sbrdf.inputs["Emission Strength"].links[0].from_node == conversion
    twin = converted.node_tree.nodes[names.TWIN_NODE]
    assert not twin.inputs["Emission Strength"].is_linked
    assert twin.inputs["Normal"].is_linked and twin.inputs["Base Color"].is_linked
    # the user's material is kept as it was, its emission texture included
    assert mat.use_fake_user and bsdf.inputs["Emission Strength"].is_linked
    # a second run rebinds the probe and keeps the carried chains as they are
    assert bpy.ops.platelight.apply_sbrdf() == {"FINISHED"}
    assert ob.active_material == converted
    nodes = converted.node_tree.nodes
    assert [n.name for n in nodes if n.name.startswith(names.PRINCIPLED_CONVERSION)] == [conversion.name]
    assert sbrdf.inputs["Diffuse Albedo"].links[0].from_node == conversion
    assert sum(n.bl_idname == "ShaderNodeBsdfPrincipled" for n in nodes) == 1
