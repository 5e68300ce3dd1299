"""Differential compositing in headless Cycles: the plate passes through bit-exact where nothing
touches it, phantoms hide CG behind them, a sun's shadow falls where the sun direction says, and
the compositor group computes the formulas of node_groups/composite.py (numpy reference)."""
import importlib
import math
import pathlib

import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.exr_io import read_exr, write_exr
from platelight.addon.ibl.equirect import texel_directions

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


def grey_world(bpy, scene, value=0.15):
    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs[0].default_value = (value, value, value, 1.0)
    scene.world = world


def render(bpy, scene, path):
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path, "RGBA")


def render_with_passes(bpy, scene, folder):
    ops_module("composite").add_pass_outputs(scene, str(folder) + "/")
    out = render(bpy, scene, folder / "composite.exr")
    return out, {n: read_exr(folder / f"{n}.exr", "RGBA") for n in ("CG", "Shadows")}


def ground_points(bpy, scene):
    """World point where each pixel's centre ray meets z = 0 (NaN above the horizon): an
    independent pinhole model from the camera's own frame."""
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


@pytest.mark.parametrize("method", ["CATCHER", "DIFFERENTIAL"])
def test_plate_unchanged_where_nothing_touches_it(bpy_clean, tmp_path, method):
    bpy = bpy_clean
    # sun only, direct light only: what the CG touches is then exactly its silhouette and its
    # sun shadow (a sky would be occluded by the sphere, a little, from the whole ground)
    scene, plate = build_scene(bpy, tmp_path, method, bounces=0, world=0.0)
    out, passes = render_with_passes(bpy, scene, tmp_path)
    ground, origin, rays = ground_points(bpy, scene)
    touched = sphere_hit(origin, rays, margin=0.08)
    shadow = in_shadow(np.nan_to_num(ground)) & np.isfinite(ground[..., 0])
    import cv2

    touched |= cv2.dilate(shadow.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    free = ~touched
    assert free.mean() > 0.8
    diff = np.abs(out[..., :3] - plate).max(axis=2)
    assert diff[free].max() <= 1e-6, f"{(diff[free] > 1e-6).sum()} untouched pixels changed"
    # and the CG and its shadow did change the pixels they touch
    assert passes["CG"][..., 3][inner(sphere_hit(origin, rays))].min() > 0.99
    assert np.median(passes["Shadows"][..., 0][shadow & ~sphere_hit(origin, rays, margin=0.05)]) < 0.5


def test_plate_unchanged_wherever_render_says_untouched_full_light_paths(bpy_clean, tmp_path):
    """With every light path on (bounces, world light), each pixel that the CG does not reach
    (alpha 0 and shadow ratio exactly 1) is bit-exact, and that is most of the frame."""
    bpy = bpy_clean
    scene, plate = build_scene(bpy, tmp_path, "CATCHER")
    out, passes = render_with_passes(bpy, scene, tmp_path)
    free = (passes["CG"][..., 3] == 0) & np.all(passes["Shadows"][..., :3] == 1, axis=2)
    assert free.mean() > 0.6
    assert np.abs(out[..., :3] - plate)[free].max() <= 1e-6


@pytest.mark.parametrize("method", ["CATCHER", "DIFFERENTIAL"])
def test_phantom_in_front_hides_cg(bpy_clean, tmp_path, method):
    bpy = bpy_clean
    scene, plate = build_scene(bpy, tmp_path, method)
    ground, origin, rays = ground_points(bpy, scene)
    behind = inner(sphere_hit(origin, rays))
    out0, passes0 = render_with_passes(bpy, scene, tmp_path)
    assert passes0["CG"][..., 3][behind].min() > 0.99  # visible without the wall
    # a real wall (phantom) between the camera and the sphere, facing the camera
    wall = add_plane(bpy, scene, size=2.5, name="Wall", location=(0, -2.0, 1.25),
                     rotation=(math.radians(90), 0, 0))
    wall.platelight.phantom = True
    assert bpy.ops.platelight.setup_composite(method=method, samples=16) == {"FINISHED"}
    out, passes = render_with_passes(bpy, scene, tmp_path)
    assert passes["CG"][..., 3][behind].max() == 0.0
    # where the wall hides the sphere the plate shows (the sun is behind the wall's back: the
    # wall is in its own shadow either way, so the ratio there is 1 up to bounce light)
    np.testing.assert_allclose(out[..., :3][behind], plate[behind], rtol=0.05)


def test_sun_shadow_falls_where_the_probe_sun_says(bpy_clean, tmp_path):
    """A probe with a small sun -> platelight.lights_from_probe -> the sphere's shadow on the
    phantom ground lies where the analytic shadow of that direction is."""
    bpy = bpy_clean
    scene = bpy.context.scene
    sun_dir = np.array([-0.5, 0.3, 0.75])
    sun_dir /= np.linalg.norm(sun_dir)
    dirs = texel_directions(128, 256)
    probe = np.zeros((128, 256, 3), np.float32)  # a sun alone: a single light
    probe[dirs @ sun_dir > math.cos(math.radians(1.0))] = 3.0e3
    write_exr(tmp_path / "probe.exr", probe)
    random_plate(tmp_path / "plate.exr")
    add_camera(bpy, scene)
    add_plane(bpy, scene).platelight.phantom = True
    add_sphere(bpy, scene)
    grey_world(bpy, scene, 0.05)
    scene.platelight.world_probe = str(tmp_path / "probe.exr")
    assert bpy.ops.platelight.lights_from_probe(count=1) == {"FINISHED"}
    assert [ob.name for ob in bpy.data.collections["PlateLight Lights"].objects] == ["PlateLight Sun"]
    sun = bpy.data.objects["PlateLight Sun"]
    from mathutils import Vector

    made_dir = np.array(sun.matrix_world.to_3x3() @ Vector((0, 0, 1)))
    assert math.degrees(math.acos(min(1.0, made_dir @ sun_dir))) < 0.5
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=8) == {"FINISHED"}
    out, passes = render_with_passes(bpy, scene, tmp_path)
    ground, origin, rays = ground_points(bpy, scene)
    on_ground = np.isfinite(ground[..., 0]) & ~sphere_hit(origin, rays, margin=0.05)
    measured = (passes["Shadows"][..., 1] < 0.5) & on_ground
    expected = in_shadow(np.nan_to_num(ground), sun_dir) & on_ground
    assert expected.sum() > 30
    iou = (measured & expected).sum() / (measured | expected).sum()
    assert iou > 0.8, f"shadow IoU {iou:.2f}"
    # the visible part of the shadow has its centre where the analytic one has (to 5 cm)
    assert np.linalg.norm(ground[measured][:, :2].mean(0) - ground[expected][:, :2].mean(0)) < 0.05


def _group_test_tree(bpy, scene, images, settings):
    tree = bpy.data.node_groups.new("Group Test", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    group = importlib.import_module(f"{support.EXT_MODULE}.node_groups.composite").build_differential_group()
    node = tree.nodes.new("CompositorNodeGroup")
    node.node_tree = group
    for name, path in images.items():
        img = tree.nodes.new("CompositorNodeImage")
        img.image = bpy.data.images.load(str(path))
        img.image.colorspace_settings.name = "Linear Rec.709"
        img.image.alpha_mode = "PREMUL"
        tree.links.new(img.outputs["Image"], node.inputs[name])
    for name, value in settings.items():
        node.inputs[name].default_value = value
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(node.outputs["Image"], out.inputs["Image"])
    scene.compositing_node_group = tree
    return tree


@pytest.mark.parametrize("form", ["ratio", "additive", "tone"])
def test_group_matches_numpy_reference(bpy_clean, tmp_path, form):
    """The compositor group against the formulas written out in numpy, on random images."""
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 32, 16
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    ops_module("composite").set_plate_colour_management(scene)
    rng = np.random.default_rng(3)
    shape = (16, 32)
    plate = rng.uniform(0.05, 2.0, shape + (3,))
    alpha = rng.choice([0.0, 0.3, 1.0], shape)[..., None]
    cg = rng.uniform(0, 3, shape + (3,)) * alpha
    without = rng.uniform(0.0, 1.5, shape + (3,))
    without[0, :4] = 0.0  # division guard
    with_ = without * rng.uniform(0.2, 1.8, shape + (3,))
    with_[1, :4] = 50.0   # clamp
    files = {}
    for name, img in (("Plate", plate), ("CG", np.concatenate([cg, alpha], -1)),
                      ("With", with_), ("Without", without)):
        files[name] = tmp_path / f"{name}.exr"
        write_exr(files[name], img.astype(np.float32))
    settings = {"Ratio Form": 0.0 if form == "additive" else 1.0, "Shadow Clamp": 4.0}
    exposure = 0.0
    if form == "tone":
        exposure = 0.7
        settings.update({"CG Exposure": exposure, "Tone Map": 1.0})
    _group_test_tree(bpy, scene, files, settings)
    out = render(bpy, scene, tmp_path / "out.exr")[..., :3]
    # numpy reference
    cg_rgb = cg * 2.0 ** exposure
    if form == "tone":
        cg_rgb = cg_rgb / (1.0 + cg_rgb)
    if form == "additive":
        local = plate + with_ - without
    else:
        local = plate * np.minimum(with_ / np.maximum(without, 1e-6), 4.0)
    expected = cg_rgb + (1 - alpha) * local
    np.testing.assert_allclose(out, expected, rtol=2e-5, atol=2e-5)
