"""Scene builders and an independent pinhole/shadow geometry for the compositing tests and the
compositing benchmark (bpy; importable from tests because tests/ is on sys.path)."""
import importlib
import math

import numpy as np

import support
from platelight.addon.exr_io import read_exr, write_exr
from support import compat

W, H = 96, 54
SUN_DIR = np.array([0.45, -0.35, 0.82])
SUN_DIR = SUN_DIR / np.linalg.norm(SUN_DIR)
SPHERE_C = np.array([0.0, 0.0, 0.5])
SPHERE_R = 0.5


def ops_module(name):
    return importlib.import_module(f"{support.EXT_MODULE}.operators.{name}")


def random_plate(path, seed=0):
    rng = np.random.default_rng(seed)
    plate = (0.2 + 0.6 * rng.random((H, W, 3))).astype(np.float32)
    write_exr(path, plate)
    return plate


def add_armature(bpy, scene, bones):
    """An armature object "Rig" in ``scene`` with ``bones``: (name, head, tail, parent name or None),
    each child connected to its parent."""
    rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    for name, head, tail, parent in bones:
        bone = rig.data.edit_bones.new(name)
        bone.head, bone.tail = head, tail
        if parent is not None:
            bone.parent, bone.use_connect = rig.data.edit_bones[parent], True
    bpy.ops.object.mode_set(mode="OBJECT")
    return rig


def add_camera(bpy, scene):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -6.0, 2.5)
    cam.rotation_euler = (math.radians(72), 0.0, 0.0)
    return cam


def add_sphere(bpy, scene, location=SPHERE_C, radius=SPHERE_R, name="Sphere"):
    mesh = bpy.data.meshes.new(name)
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    for poly in mesh.polygons:
        poly.use_smooth = True
    ob = bpy.data.objects.new(name, mesh)
    ob.location = tuple(location)
    scene.collection.objects.link(ob)
    return ob


def add_plane(bpy, scene, size=400.0, name="Ground", location=(0, 0, 0), rotation=(0, 0, 0)):
    mesh = bpy.data.meshes.new(name)
    s = size / 2
    mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    ob.rotation_euler = rotation
    scene.collection.objects.link(ob)
    return ob


def add_sun(bpy, scene, direction=SUN_DIR, strength=4.0):
    from mathutils import Vector

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = strength
    sun.data.angle = 0.0
    sun.rotation_euler = Vector(tuple(direction)).to_track_quat("Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    return sun


def principled_material(name, roughness, colour=None, metallic=0.0):
    """A new Principled material of that roughness and metallic (base colour: Blender's, unless given)."""
    material = compat().new_material(name)
    bsdf = compat().node_tree(material).nodes["Principled BSDF"]
    if colour is not None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    return material


def metal_material(name, colour, roughness):
    """A new Principled metal (Metallic 1) of that base colour and roughness."""
    return principled_material(name, roughness, colour, metallic=1.0)


def grey_world(bpy, scene, value=0.15):
    world = compat().new_world("World")
    world.node_tree.nodes["Background"].inputs[0].default_value = (value, value, value, 1.0)
    scene.world = world


def render(bpy, scene, path):
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path, "RGBA")


def render_with_passes(bpy, scene, folder):
    compositor_tree = importlib.import_module(f"{support.EXT_MODULE}.node_groups.compositor_tree")
    compositor_tree.add_pass_outputs(scene, str(folder) + "/")
    out = render(bpy, scene, folder / "composite.exr")
    return out, {n: read_exr(compositor_tree.pass_output_path(scene, str(folder), n), "RGBA")
                 for n in ("CG", "Shadows")}


def ground_points(bpy, scene):
    """World point where each pixel's centre ray meets z = 0 (NaN above the horizon): an
    independent pinhole model from the camera's own frame."""
    bpy.context.view_layer.update()  # matrix_world of a camera just placed
    cam = scene.camera
    frame = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    # view_frame: top-right, bottom-right, bottom-left, top-left
    tr, br, bl, tl = (np.array(v) for v in frame)
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    top = tl[None, :] + u[:, None] * (tr - tl)[None, :]
    bottom = bl[None, :] + u[:, None] * (br - bl)[None, :]
    pts = top[None, :, :] + v[:, None, None] * (bottom - top)[None, :, :]
    origin = np.array(cam.matrix_world.translation)
    rays = pts - origin
    t = -origin[2] / rays[..., 2]
    ground = origin + t[..., None] * rays
    ground[t <= 0] = np.nan
    return ground, origin, rays


def sphere_hit(origin, rays, centre=SPHERE_C, radius=SPHERE_R, margin=0.0):
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    oc = origin - centre
    b = d @ oc
    return b * b - (oc @ oc - (radius + margin) ** 2) >= 0


def inner(mask, pixels=2):
    """The mask without its outer ``pixels`` (where the pixel filter blends edges)."""
    import cv2

    return cv2.erode(mask.astype(np.uint8), np.ones((2 * pixels + 1,) * 2, np.uint8)).astype(bool)


def in_shadow(ground, direction=SUN_DIR, centre=SPHERE_C, radius=SPHERE_R):
    """Ground points whose ray towards the sun meets the sphere (analytic)."""
    oc = ground - centre
    b = oc @ direction
    return (b * b - ((oc * oc).sum(-1) - radius ** 2) >= 0) & (b < 0)


def build_scene(bpy, tmp_path, method="CATCHER", samples=16, bounces=None, world=0.15):
    scene = bpy.context.scene
    plate = random_plate(tmp_path / "plate.exr")
    add_camera(bpy, scene)
    add_plane(bpy, scene).platelight.phantom = True
    add_sphere(bpy, scene)
    add_sun(bpy, scene)
    grey_world(bpy, scene, world)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(method=method, samples=samples) == {"FINISHED"}
    if bounces is not None:
        scene.cycles.max_bounces = bounces
    return scene, plate
