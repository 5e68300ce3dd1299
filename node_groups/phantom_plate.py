"""The material "PlateLight Phantom Plate" (names.PHANTOM_PLATE_MATERIAL): a diffuse surface
whose albedo is the real surface's, estimated from the plate (operators/phantoms.py:
plate / the phantoms rendered white), projected from the camera pose of the frame it was made
at. Shaded by the scene's lights it shows the plate where nothing changes, and the CG's shadows
and light where the CG is: in reflections on CG, in light bounced onto CG, in probes, and on the
shadow catcher. Rebuilt in place (idempotent)."""
import bpy
import numpy as np

from .. import compat
from ..addon import names
from ._build import Graph
from .baked_shadow import ensure_ratio_group, seen_at


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


def build_phantom_plate_material(albedo_image, radiance_image, world_to_camera, pinhole, size, fallback):
    """The material (created or rebuilt). ``world_to_camera``: 4x4 of the camera pose the albedo
    and radiance maps were made at; ``pinhole`` (fx, fy, cx, cy) and ``size`` (width, height) of
    their images; ``fallback``: the albedo where the map has none (outside it, or where the camera
    saw no light).

    In a view layer whose names.FILMED_PHANTOMS_KEY is 1 (the baked composite's CG layer), a point
    the camera filmed emits what it filmed there times the baked shadow ratio
    (names.BAKED_RATIO_GROUP): the real surface as the plate shows it, with the CG's shadow on it,
    so a path-traced CG object's rays end there without noise (docs/decisions.md, "Filmed
    phantoms"). Points the camera did not film keep the diffuse albedo, path-traced."""
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
    # the maps know a point inside their frame (half a pixel of slack at the rim, where EXTEND
    # repeats the edge) and in front of the camera; the albedo's alpha says where it knows it
    in_front = g.math("GREATER_THAN", depth, 0.0)
    inside = in_front
    for coord, pixels in ((u, width), (v, height)):
        margin = 0.5 / pixels
        inside = g.math("MULTIPLY", inside, g.math("GREATER_THAN", coord, -margin))
        inside = g.math("MULTIPLY", inside, g.math("LESS_THAN", coord, 1.0 + margin))
    stored = g.node("ShaderNodeTexImage", image=radiance_image, extension="EXTEND", interpolation="Closest")
    g.link(uv.outputs[0], stored.inputs["Vector"])
    eye = np.linalg.inv(np.asarray(world_to_camera, dtype=np.float64))[:3, 3]
    distance = g.vmath("LENGTH", g.vmath("SUBTRACT", position, tuple(float(c) for c in eye)))
    # the point the camera saw there, not one hidden behind it (the tolerance of the shadow bake's
    # own distance test); the radiance map's A is 0 where the camera saw no phantom
    seen = seen_at(g, distance, stored.outputs["Alpha"])
    # a point the camera saw takes the albedo there; a hidden one its own phantom's (names.
    # HIDDEN_ALBEDO_KEY), not the colour of the pixel in front of it; a phantom without the
    # property (made after the set-up) takes the fallback
    known = g.math("MULTIPLY", g.math("MULTIPLY", tex.outputs["Alpha"], inside), seen)
    own = g.node("ShaderNodeAttribute", attribute_type="OBJECT", attribute_name=names.HIDDEN_ALBEDO_KEY)
    hidden = g.mix("RGBA", g.math("GREATER_THAN", own.outputs["Alpha"], 0.5),
                   (*[float(c) for c in fallback], 1.0), own.outputs["Color"])
    albedo = g.mix("RGBA", known, hidden, tex.outputs["Color"])
    diffuse = g.node("ShaderNodeBsdfDiffuse")
    g.link(albedo, diffuse.inputs["Color"])
    out = g.node("ShaderNodeOutputMaterial")
    surface = _filmed(g, diffuse.outputs[0], uv.outputs[0], in_front, inside, seen, stored, radiance_image)
    g.link(_held_out(g, surface), out.inputs["Surface"])
    # rays reach the filmed surface by their own sampling: as a lamp it would be a big, textured
    # one Cycles samples for nothing (it is only on in one layer, and lights the CG only by bounce)
    mat.cycles.emission_sampling = "NONE"
    return mat


def _held_out(g, surface):
    """``surface``, or a holdout for camera rays where the layer holds the phantoms out: Cycles
    evaluates a held-out object's material for every camera ray that meets it, and skips a mix's
    branch whose weight is 0 (docs/decisions.md, "Filmed phantoms")."""
    switch = g.node("ShaderNodeAttribute", attribute_type="VIEW_LAYER", attribute_name=names.HELD_OUT_PHANTOMS_KEY)
    camera = g.node("ShaderNodeLightPath").outputs["Is Camera Ray"]
    mix = g.node("ShaderNodeMixShader")
    g.link(g.math("MULTIPLY", switch.outputs["Fac"], camera), mix.inputs["Fac"])
    g.link(surface, mix.inputs[1])
    g.link(g.node("ShaderNodeHoldout").outputs["Holdout"], mix.inputs[2])
    return mix.outputs["Shader"]


# The node that makes a point outside the frame take the frame's edge (1 there); the CG-layer
# benchmark sets its first input to 0 to measure the edge's worth
BEYOND_FRAME_NODE = "Beyond the frame: its edge"


def _filmed(g, diffuse, uv, in_front, inside, seen, stored, radiance_image):
    """``diffuse``, or where the layer asks for it and the camera filmed this point, the filmed
    radiance times the baked ratio (an emission).

    A point in front of the camera but outside its frame gets the frame's edge (the phantom there
    carried on, as EXTEND repeats it): path-traced instead, the far floor beyond a frame's top
    edge is a noisy band in a mirror's otherwise noise-free reflection, which the denoiser leaves
    noisy."""
    colour = g.node("ShaderNodeTexImage", image=radiance_image, extension="EXTEND", interpolation="Linear")
    g.link(uv, colour.inputs["Vector"])
    beyond_frame = g.math("SUBTRACT", 1.0, inside)
    beyond_frame.node.name = beyond_frame.node.label = BEYOND_FRAME_NODE
    seen_there = g.math("MAXIMUM", beyond_frame, seen)
    filmed = g.math("MULTIPLY", g.math("GREATER_THAN", stored.outputs["Alpha"], 0.0), seen_there)
    ratio = g.node("ShaderNodeGroup")
    ratio.name = ratio.label = names.BAKED_RATIO_GROUP
    ratio.node_tree = ensure_ratio_group()
    emit = g.node("ShaderNodeEmission")
    g.link(g.vmath("MULTIPLY", colour.outputs["Color"], ratio.outputs["Ratio"]), emit.inputs["Color"])
    switch = g.node("ShaderNodeAttribute", attribute_type="VIEW_LAYER", attribute_name=names.FILMED_PHANTOMS_KEY)
    factor = g.math("MULTIPLY", g.math("MULTIPLY", switch.outputs["Fac"], in_front), filmed)
    mix = g.node("ShaderNodeMixShader")
    g.link(factor, mix.inputs["Fac"])
    g.link(diffuse, mix.inputs[1])
    g.link(emit.outputs["Emission"], mix.inputs[2])
    return mix.outputs["Shader"]
