"""Redistortion of the rendered layers onto the plate (compositor, bpy): a Map UV node reading
the ST-map that operators/lens.py writes ("PlateLight Lens ST-Map": for each plate pixel, where
the undistorted overscan render shows that point) after every Render Layers output of the
composite tree. The shadow catcher's ratio is mapped as ratio - 1 and 1 is added back, so a pixel
nothing touched stays exactly 1 (bilinear weights of exact zeros stay zero) and the plate outside
the CG is bit-exact. The plate itself is never resampled."""
import bpy

from .. import compat
from ..addon import names


def wire_redistortion(scene, tree):
    """A Map UV node (the ST-map) after every Render Layers output used in ``tree``: the CG and
    shadow layers are rendered undistorted and land on the plate through its own lens. Nothing
    when the scene has no lens. Idempotent: the tree is rebuilt before this runs."""
    stmap = bpy.data.images.get(names.LENS_STMAP_IMAGE)
    if not scene.get(names.LENS_KEY) or stmap is None:
        return 0
    nodes, links = tree.nodes, tree.links
    source = nodes.new("CompositorNodeImage")
    source.name = source.label = names.LENS_STMAP_IMAGE
    source.image = stmap
    source.location = (-1100, -800)
    count = 0
    for link in [l for l in links if l.from_node.bl_idname == "CompositorNodeRLayers"]:
        out_socket, to_socket, layer = link.from_socket, link.to_socket, link.from_node
        x, y = layer.location
        links.remove(link)
        ratio = out_socket.name == "Shadow Catcher"
        value = out_socket
        if ratio:   # map (ratio - 1): bilinear weights of exact zeros stay exactly zero
            value = _math(nodes, links, "SUBTRACT", value, 1.0, (x + 150, y - 40 * count))
        elif out_socket.name == "Image":
            # Blender 5.3's Map UV samples a Render Layers image wider than bilinear when it is
            # linked directly (a CG square lost 1.3 % of its area, its centroid moved 0.41 px);
            # through any node, here one that keeps the alpha, it samples exactly (measured).
            keep = nodes.new("CompositorNodeSetAlpha")
            keep.location = (x + 150, y - 40 * count)
            compat.set_option(keep, "Type", "Replace Alpha")
            links.new(value, keep.inputs["Image"])
            links.new(layer.outputs["Alpha"], keep.inputs["Alpha"])
            value = keep.outputs["Image"]
        remap = nodes.new("CompositorNodeMapUV")
        remap.label = names.REDISTORT_NODE
        remap.location = (x + 300, y - 40 * count)
        if "Interpolation" in remap.inputs:     # Blender 5: a menu socket; 4.5: EWA filtering only
            remap.inputs["Interpolation"].default_value = "Bilinear"
        links.new(value, remap.inputs["Image"])
        links.new(source.outputs["Image"], remap.inputs["UV"])
        result = remap.outputs["Image"]
        if ratio:
            result = _math(nodes, links, "ADD", result, 1.0, (x + 450, y - 40 * count))
        links.new(result, to_socket)
        count += 1
    return count


def _math(nodes, links, operation, socket, value, location):
    node = compat.compositor_math(nodes, operation)
    node.location = location
    links.new(socket, node.inputs[0])
    node.inputs[1].default_value = value
    return node.outputs[0]
