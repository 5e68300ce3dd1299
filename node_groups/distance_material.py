"""The temporary material that emits each surface's distance from the camera (Camera Data's View
Distance; for a panoramic camera the radial distance from its centre) in R, and its object's pass
index in G: the probe bake's distance maps (operators/bake/distance_render.py, R only) and the
plate frame's phantom distances and objects (operators/phantoms.py) are renders of it. Made
on first use, removed after."""
import bpy

from .. import compat
from ..addon import names


def distance_material():
    """The material emitting View Distance, made on first use; ``remove_distance_material()``
    takes it away again."""
    material = bpy.data.materials.get(names.PROBE_DISTANCE)
    if material is None:
        material = compat.new_material(names.PROBE_DISTANCE)
        tree = material.node_tree
        tree.nodes.clear()
        camera = tree.nodes.new("ShaderNodeCameraData")
        index = tree.nodes.new("ShaderNodeObjectInfo")
        rgb = tree.nodes.new("ShaderNodeCombineXYZ")
        emit = tree.nodes.new("ShaderNodeEmission")
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        tree.links.new(camera.outputs["View Distance"], rgb.inputs["X"])
        tree.links.new(index.outputs["Object Index"], rgb.inputs["Y"])
        tree.links.new(rgb.outputs["Vector"], emit.inputs["Color"])
        tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return material


def remove_distance_material():
    material = bpy.data.materials.get(names.PROBE_DISTANCE)
    if material is not None:
        bpy.data.materials.remove(material)
