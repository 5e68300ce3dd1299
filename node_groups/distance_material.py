"""The temporary material that emits each surface's distance from the camera (Camera Data's View
Distance; for a panoramic camera the radial distance from its centre): the probe bake's distance
maps (operators/bake/distance_render.py) and the plate frame's phantom distances
(operators/phantom_albedo.py) are renders of it. Made on first use, removed after."""
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
        emit = tree.nodes.new("ShaderNodeEmission")
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        tree.links.new(camera.outputs["View Distance"], emit.inputs["Color"])
        tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return material


def remove_distance_material():
    material = bpy.data.materials.get(names.PROBE_DISTANCE)
    if material is not None:
        bpy.data.materials.remove(material)
