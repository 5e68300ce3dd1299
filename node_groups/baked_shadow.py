"""The material the baked-shadow layer renders every phantom with (view-layer material override):
it emits 1 + (baked ratio − 1) read from the shot's shadow panorama along the direction from the
panorama's centre to the shading point, so the layer's image is the shadow ratio the catcher pass
would have given, with no path tracing (addon/compositing/baked_shadows.py).

A point the panorama saw behind something nearer (a phantom's hidden side) is told apart by the
panorama's distance map, as the probe's parallax search does: there it emits 1 (no change).

The ratio lookup is a node group of its own (names.BAKED_RATIO_GROUP): the phantoms' plate
material reads it too, to show the CG's rays the filmed plate shadowed (node_groups/phantom_plate.py)."""
from __future__ import annotations

import bpy

from .. import compat
from ..addon import names
from ._build import (Graph, hold_per_frame, io_nodes, shader_group, strength_against_film_exposure,
                     sync_interface)
from .probe_maps import SEQUENCE_FRAMES

# A point counts as the one the panorama saw when it lies no farther than this beyond the
# distance stored for its direction (relative, plus an absolute 1 cm for texels at the horizon).
SEEN_TOLERANCE = 0.05
SEEN_SLACK = 0.01


def seen_at(g, distance, stored):
    """1 where a point at ``distance`` is the one a render that stored ``stored`` for its direction
    saw (no farther than the tolerance beyond it), else 0."""
    return g.math("LESS_THAN", distance, g.math("MULTIPLY_ADD", stored, 1.0 + SEEN_TOLERANCE, SEEN_SLACK))


def baked_ratio_group(ratio_path: str | None = None, distance_path: str | None = None, centre=None,
                      moving: dict | None = None):
    """The group (made or rebuilt in place, so materials using it follow a new bake) whose output
    *Ratio* is 1 + (baked ratio − 1) at the shading point, read from ``ratio_path`` (ratio − 1, RGB)
    and ``distance_path`` (radial distances), both panoramas centred at ``centre``; without a bake
    (no paths), 1 everywhere. ``moving`` (a moving CG's shadows baked per frame: "ratio" and
    "distance", the first files of their sequences, and "centres", {frame: centre}): times that
    frame's ratio, read the same way from that frame's centre. A bake rebuilds it;
    ``ensure_ratio_group`` gives the one there is."""
    tree = shader_group(names.BAKED_RATIO_GROUP)
    sync_interface(tree, [("OUTPUT", "Ratio", "NodeSocketColor", {})])
    tree.nodes.clear()
    tree.animation_data_clear()         # a per-frame bake's keyed centres
    g = Graph(tree)
    _gin, gout = io_nodes(g)
    if ratio_path is None:
        one = g.node("ShaderNodeRGB")
        one.outputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        g.link(one.outputs["Color"], gout.inputs["Ratio"])
        return tree
    origin = g.node("ShaderNodeCombineXYZ")
    origin.name = origin.label = "Panorama Centre"
    for axis, value in zip("XYZ", centre):
        origin.inputs[axis].default_value = float(value)
    ratio = _panorama_ratio(g, ratio_path, distance_path, origin.outputs["Vector"], sequence=False)
    if moving:
        origin = g.node("ShaderNodeCombineXYZ")
        origin.name = origin.label = "Moving Panorama Centre"
        for index, axis in enumerate("XYZ"):
            hold_per_frame(origin.inputs[axis], {f: float(c[index]) for f, c in moving["centres"].items()})
        moving_ratio = _panorama_ratio(g, moving["ratio"], moving["distance"], origin.outputs["Vector"],
                                       sequence=True)
        # where both shadows fall, the light left is the product of what each leaves
        ratio = g.vmath("MULTIPLY", ratio, moving_ratio)
    g.link(ratio, gout.inputs["Ratio"])
    return tree


def _panorama_ratio(g, ratio_path, distance_path, origin, sequence):
    """1 + (ratio − 1) looked up from ``origin`` in the panoramas (image sequences: the scene
    frame F reads file F), where the distance panorama saw the shading point; else 1."""
    offset = g.vmath("SUBTRACT", g.node("ShaderNodeNewGeometry").outputs["Position"], origin)

    def panorama(path, interpolation):
        node = g.node("ShaderNodeTexEnvironment", interpolation=interpolation)
        node.image = bpy.data.images.load(path, check_existing=True)
        node.image.source = "SEQUENCE" if sequence else "FILE"
        node.image.reload()
        node.image.colorspace_settings.name = "Non-Color"
        if sequence:
            user = node.image_user
            user.frame_start, user.frame_offset = 1, 0
            user.frame_duration = SEQUENCE_FRAMES
            user.use_auto_refresh = True
        g.link(offset, node.inputs["Vector"])
        return node.outputs["Color"]

    ratio_minus_one = panorama(ratio_path, "Linear")
    stored = g.node("ShaderNodeSeparateColor")
    g.link(panorama(distance_path, "Closest"), stored.inputs["Color"])
    seen = seen_at(g, g.vmath("LENGTH", offset), stored.outputs["Red"])
    change = g.vmath("SCALE", ratio_minus_one, scale=seen)
    return g.vmath("ADD", change, (1.0, 1.0, 1.0))


def ensure_ratio_group():
    """The baked ratio group as it is, or one of ratio 1 where nothing was baked yet: the
    phantoms' plate material always holds it, so its shape (which a bake's input hash describes)
    does not change with the first bake."""
    return bpy.data.node_groups.get(names.BAKED_RATIO_GROUP) or baked_ratio_group()


def baked_shadow_material(ratio_path: str, distance_path: str, centre, moving=None) -> bpy.types.Material:
    """The override material (made or rebuilt in place): it emits the baked ratio group's *Ratio*
    and writes it to the AOV names.BAKED_RATIO_AOV, the group rebuilt for ``ratio_path``,
    ``distance_path``, ``centre`` and ``moving`` (baked_ratio_group)."""
    group = baked_ratio_group(ratio_path, distance_path, centre, moving)
    material = bpy.data.materials.get(names.BAKED_SHADOW_MATERIAL) or compat.new_material(names.BAKED_SHADOW_MATERIAL)
    tree = compat.shader_tree(material)
    tree.nodes.clear()
    g = Graph(tree)
    ratio = g.node("ShaderNodeGroup")
    ratio.node_tree = group
    emit = g.node("ShaderNodeEmission")
    g.link(ratio.outputs["Ratio"], emit.inputs["Color"])
    strength_against_film_exposure(emit.inputs["Strength"], bpy.context.scene)
    out = g.node("ShaderNodeOutputMaterial")
    g.link(emit.outputs["Emission"], out.inputs["Surface"])
    ensure_ratio_aov(material)
    return material


def ensure_ratio_aov(material):
    """Make the override ``material`` also write its ratio to the AOV names.BAKED_RATIO_AOV (a
    material baked without it gets it here): a shadow catcher renders transparent, so where the
    phantoms also catch a moving CG's shadow the layer's ratio is read from the AOV
    (node_groups/compositor_tree.py)."""
    tree = compat.shader_tree(material)
    if any(node.bl_idname == "ShaderNodeOutputAOV" for node in tree.nodes):
        return
    ratio = next(node for node in tree.nodes if node.bl_idname == "ShaderNodeGroup")
    aov = tree.nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = names.BAKED_RATIO_AOV
    aov.location = (ratio.location.x + 200, ratio.location.y - 200)
    tree.links.new(ratio.outputs["Ratio"], aov.inputs["Color"])
