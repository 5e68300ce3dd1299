"""The material names.PHANTOM_PLATE_MATERIAL ("PlateLight Phantom Plate"): a phantom shows the plate, projected from the plate's
camera, to every ray that is not the composite's camera ray (reflections in CG, light bounced
onto CG, probe renders), so a chrome CG object reflects the real floor and the real floor's
colour bleeds onto CG. The composite's own camera rays see a diffuse surface whose albedo is
the plate (clamped to 1): the shadow catcher needs a lit surface to measure shadows on.

Probe renders set ``scene.platelight.probe_render`` (a View Layer attribute here): there the
probe's camera rays see the plate too.

The projection is the plate camera's own (Texture Coordinate in the camera object's space,
so it follows the tracked camera), with the calibrated lens distortion (OpenCV's model written
out in math nodes) when the scene has one, so the lookup lands on the distorted plate's pixel.
Rebuilt in place (idempotent) whenever the camera, plate or lens may have changed."""
import bpy

from .. import compat
from ..addon import names
from ._build import Graph

PROBE_RENDER_ATTRIBUTE = "platelight.probe_render"


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


def build_phantom_plate_material(scene, camera, plate_image, intrinsics, frame_offset=0):
    """The material (created or rebuilt); ``intrinsics`` = (fx, fy, cx, cy, dist, width, height)
    of the plate's own camera."""
    fx, fy, cx, cy, dist, width, height = intrinsics
    k1, k2, p1, p2, k3 = (list(dist) + [0.0] * 5)[:5]
    mat = bpy.data.materials.get(names.PHANTOM_PLATE_MATERIAL) or compat.new_material(names.PHANTOM_PLATE_MATERIAL)
    tree = compat.node_tree(mat)
    tree.nodes.clear()
    g = Graph(tree)

    coords = g.node("ShaderNodeTexCoord", object=camera)
    xyz = g.node("ShaderNodeSeparateXYZ")
    g.link(coords.outputs["Object"], xyz.inputs[0])
    depth = g.math("MULTIPLY", xyz.outputs["Z"], -1.0)          # Blender cameras look down -Z
    x = g.math("DIVIDE", xyz.outputs["X"], depth)
    y = g.math("DIVIDE", g.math("MULTIPLY", xyz.outputs["Y"], -1.0), depth)   # OpenCV: y down
    xx, yy, xy = g.math("MULTIPLY", x, x), g.math("MULTIPLY", y, y), g.math("MULTIPLY", x, y)
    r2 = g.math("ADD", xx, yy)
    # radial = 1 + r2 (k1 + r2 (k2 + r2 k3))
    radial = g.math("MULTIPLY_ADD", r2, g.math("MULTIPLY_ADD", r2, g.math("MULTIPLY_ADD", r2, k3, k2), k1), 1.0)
    # xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2); yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    xd = g.math("ADD", g.math("MULTIPLY_ADD", xy, 2 * p1, g.math("MULTIPLY", x, radial)),
                g.math("MULTIPLY", g.math("MULTIPLY_ADD", xx, 2.0, r2), p2))
    yd = g.math("ADD", g.math("MULTIPLY_ADD", xy, 2 * p2, g.math("MULTIPLY", y, radial)),
                g.math("MULTIPLY", g.math("MULTIPLY_ADD", yy, 2.0, r2), p1))
    # OpenCV pixel -> Blender texture coordinates (bottom-left corner 0, pixel centres +0.5)
    u = g.math("DIVIDE", g.math("MULTIPLY_ADD", xd, fx, cx + 0.5), float(width))
    v = g.math("SUBTRACT", 1.0, g.math("DIVIDE", g.math("MULTIPLY_ADD", yd, fy, cy + 0.5), float(height)))
    uv = g.node("ShaderNodeCombineXYZ")
    g.link(u, uv.inputs[0])
    g.link(v, uv.inputs[1])

    tex = g.node("ShaderNodeTexImage", image=plate_image, extension="EXTEND", interpolation="Linear")
    g.link(uv.outputs[0], tex.inputs["Vector"])
    if plate_image.source in {"SEQUENCE", "MOVIE"}:
        user = tex.image_user
        user.frame_start = scene.frame_start
        user.frame_duration = max(1, scene.frame_end - scene.frame_start + 1)
        user.frame_offset = frame_offset
        user.use_auto_refresh = True
    in_front = g.math("GREATER_THAN", depth, 0.0)               # behind the camera: black
    plate = g.mix("RGBA", in_front, (0.0, 0.0, 0.0, 1.0), tex.outputs["Color"])
    # the plate is radiance x the camera's film exposure: the emission is the radiance
    exposure = max(getattr(scene.cycles, "film_exposure", 1.0), 1e-6)
    emission = g.node("ShaderNodeEmission")
    g.link(plate, emission.inputs["Color"])
    emission.inputs["Strength"].default_value = 1.0 / exposure
    albedo = g.mix("RGBA", 1.0, plate, plate)
    albedo.node.clamp_result = True                             # an albedo stays within 0..1
    diffuse = g.node("ShaderNodeBsdfDiffuse")
    g.link(albedo, diffuse.inputs["Color"])

    path = g.node("ShaderNodeLightPath")
    probe = g.node("ShaderNodeAttribute", attribute_type="VIEW_LAYER", attribute_name=PROBE_RENDER_ATTRIBUTE)
    diffuse_weight = g.math("MULTIPLY", path.outputs["Is Camera Ray"], g.math("SUBTRACT", 1.0, probe.outputs["Fac"]))
    shader = g.node("ShaderNodeMixShader")
    g.link(diffuse_weight, shader.inputs["Fac"])
    g.link(emission.outputs[0], shader.inputs[1])
    g.link(diffuse.outputs[0], shader.inputs[2])
    out = g.node("ShaderNodeOutputMaterial")
    g.link(shader.outputs[0], out.inputs["Surface"])
    return mat
