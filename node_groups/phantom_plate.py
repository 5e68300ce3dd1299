"""The material "PlateLight Phantom Plate" (names.PHANTOM_PLATE_MATERIAL): a diffuse surface
whose albedo is the real surface's, estimated from the plate (operators/phantom_albedo.py:
plate / the phantoms rendered white), projected from the camera pose of the frame it was made
at. Shaded by the scene's lights it shows the plate where nothing changes, and the CG's shadows
and light where the CG is: in reflections on CG, in light bounced onto CG, in probes, and on the
shadow catcher. Rebuilt in place (idempotent)."""
import bpy

from .. import compat
from ..addon import names
from ._build import Graph


def pinhole_from_camera(scene, camera):
    """OpenCV (fx, fy, cx, cy) of a Blender camera on the scene's render size (the inverse of
    addon/compositing/lens.blender_camera_fields: horizontal sensor fit)."""
    width, height = scene.render.resolution_x, scene.render.resolution_y
    cam = camera.data
    aspect = scene.render.pixel_aspect_y / scene.render.pixel_aspect_x
    if cam.sensor_fit == "VERTICAL" or (cam.sensor_fit == "AUTO" and height > width):
        fy = cam.lens * height / (cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width)
        fx = fy / aspect
        size = height
    else:
        fx = cam.lens * width / cam.sensor_width
        fy = fx * aspect
        size = width
    return fx, fy, (width - 1) / 2 - cam.shift_x * size, (height - 1) / 2 + cam.shift_y * size


def build_phantom_plate_material(albedo_image, world_to_camera, pinhole, size, fallback):
    """The material (created or rebuilt). ``world_to_camera``: 4x4 of the camera pose the albedo
    map was made at; ``pinhole`` (fx, fy, cx, cy) and ``size`` (width, height) of its image;
    ``fallback``: the albedo where the map has none (outside it, or where the camera saw no light)."""
    fx, fy, cx, cy = pinhole
    width, height = size
    mat = bpy.data.materials.get(names.PHANTOM_PLATE_MATERIAL) or compat.new_material(names.PHANTOM_PLATE_MATERIAL)
    tree = compat.node_tree(mat)
    tree.nodes.clear()
    g = Graph(tree)

    position = g.node("ShaderNodeNewGeometry").outputs["Position"]
    rows = [g.vmath("DOT_PRODUCT", position, tuple(float(v) for v in world_to_camera[i][:3])) for i in range(3)]
    cam = [g.math("ADD", rows[i], float(world_to_camera[i][3])) for i in range(3)]
    depth = g.math("MULTIPLY", cam[2], -1.0)                   # Blender cameras look down -Z
    x = g.math("DIVIDE", cam[0], depth)
    y = g.math("DIVIDE", g.math("MULTIPLY", cam[1], -1.0), depth)   # OpenCV: y down
    # OpenCV pixel -> Blender texture coordinates (bottom-left corner 0, pixel centres +0.5)
    u = g.math("DIVIDE", g.math("MULTIPLY_ADD", x, fx, cx + 0.5), float(width))
    v = g.math("SUBTRACT", 1.0, g.math("DIVIDE", g.math("MULTIPLY_ADD", y, fy, cy + 0.5), float(height)))
    uv = g.node("ShaderNodeCombineXYZ")
    g.link(u, uv.inputs[0])
    g.link(v, uv.inputs[1])
    tex = g.node("ShaderNodeTexImage", image=albedo_image, extension="EXTEND", interpolation="Linear")
    g.link(uv.outputs[0], tex.inputs["Vector"])
    # the map's alpha says where it knows the albedo: inside its frame (half a pixel of slack at
    # the rim, where EXTEND repeats the edge) and in front of the camera
    known = g.math("MULTIPLY", tex.outputs["Alpha"], g.math("GREATER_THAN", depth, 0.0))
    for coord, pixels in ((u, width), (v, height)):
        margin = 0.5 / pixels
        known = g.math("MULTIPLY", known, g.math("GREATER_THAN", coord, -margin))
        known = g.math("MULTIPLY", known, g.math("LESS_THAN", coord, 1.0 + margin))
    albedo = g.mix("RGBA", known, (*[float(c) for c in fallback], 1.0), tex.outputs["Color"])
    diffuse = g.node("ShaderNodeBsdfDiffuse")
    g.link(albedo, diffuse.inputs["Color"])
    out = g.node("ShaderNodeOutputMaterial")
    g.link(diffuse.outputs[0], out.inputs["Surface"])
    return mat
