"""The probe's layer behind its first surface (addon/ibl/distance.py, parallax_layers): what the
centre would see along each direction if the first object there were not in the way.

A sharp reflector beside a near phantom (a mirror ball beside a box) reflects, past the box's
edges, things its probe's centre cannot see: the floor behind the box, the sky over it. The
distance-impostor search then meets the box's silhouette and reads the box there (a red rim on
the box's reflection; the mirror + box benchmark's object PSNR 36.0 dB, 76 % of its error in
those pixels). Two more renders fill them: the panorama and its distance map with camera rays
passing through the first object they meet (transparent at their first hit and at the back
faces that close that object). Only camera rays peel; the light, shadows and bounces are the
scene's as they are.

The peel is a Mix Shader put in front of each material's output for the one render and taken
out again (``peeled``); materials that cannot be edited (linked from a library) stay opaque,
which leaves the first layer there."""
from __future__ import annotations

from contextlib import contextmanager

import bpy

from ...addon import names
from ...node_groups.ray_twin import material_output


def add_peel(tree, shader_socket, output_node):
    """Link ``shader_socket`` to ``output_node``'s Surface through a Mix Shader that is a
    Transparent BSDF for camera rays at their first hit and on back faces; returns the nodes
    added."""
    path = tree.nodes.new("ShaderNodeLightPath")
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    first = tree.nodes.new("ShaderNodeMath")
    first.operation = "LESS_THAN"
    first.inputs[1].default_value = 0.5
    tree.links.new(path.outputs["Transparent Depth"], first.inputs[0])
    either = tree.nodes.new("ShaderNodeMath")
    either.operation = "MAXIMUM"
    tree.links.new(first.outputs[0], either.inputs[0])
    tree.links.new(geometry.outputs["Backfacing"], either.inputs[1])
    camera = tree.nodes.new("ShaderNodeMath")
    camera.operation = "MULTIPLY"
    tree.links.new(either.outputs[0], camera.inputs[0])
    tree.links.new(path.outputs["Is Camera Ray"], camera.inputs[1])
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(camera.outputs[0], mix.inputs[0])
    tree.links.new(shader_socket, mix.inputs[1])
    tree.links.new(clear.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], output_node.inputs["Surface"])
    return [path, geometry, first, either, camera, clear, mix]


def peeled_distance_material():
    """The bake's distance material (node_groups/distance_material.py) peeled: made on first
    use, removed with the other at the bake's end."""
    material = bpy.data.materials.get(names.PROBE_DISTANCE_BEHIND)
    if material is None:
        from ...node_groups.distance_material import distance_material

        material = distance_material().copy()
        material.name = names.PROBE_DISTANCE_BEHIND
        tree = material.node_tree
        out = material_output(tree)
        add_peel(tree, out.inputs["Surface"].links[0].from_socket, out)
    return material


def remove():
    material = bpy.data.materials.get(names.PROBE_DISTANCE_BEHIND)
    if material is not None:
        bpy.data.materials.remove(material)


def _scene_materials(scene):
    seen = {}
    for ob in scene.objects:
        for slot in getattr(ob, "material_slots", ()):
            material = slot.material
            if material is not None and material.library is None and material.node_tree is not None:
                seen[material.name_full] = material
    return list(seen.values())


@contextmanager
def peeled(scene):
    """Every editable material of the scene's objects peeled (``add_peel``) while the block runs;
    each is given back its own link to its output afterwards, whatever happens in the block."""
    changed = []
    try:
        for material in _scene_materials(scene):
            tree = material.node_tree
            out = material_output(tree)
            if out is None or not out.inputs["Surface"].links:
                continue
            source = out.inputs["Surface"].links[0].from_socket
            changed.append((tree, out, source, add_peel(tree, source, out)))
        yield
    finally:
        for tree, out, source, added in changed:
            for node in added:
                tree.nodes.remove(node)
            tree.links.new(source, out.inputs["Surface"])
