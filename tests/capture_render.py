"""Ground truth rendered by Blender itself for the capture tests and benchmark.

* ``render_target_frames``: a printed marker/board (a textured, emissive plane in the world frame
  of design.md) filmed by a known moving camera with Cycles.
* ``render_mirror_ball``: a perfect mirror sphere under a known HDRI seen by an orthographic
  camera, saved as a linear float EXR (the brackets are made from it with a known tone curve).

Everything here needs bpy (pass the module in); nothing is mocked."""
from __future__ import annotations

import math
import os
import pathlib

import numpy as np
from support import compat

PX_PER_M = 5000.0           # texture resolution: 0.04 m squares = 200 px, 0.12 m marker = 600 px
MARGIN_M = 0.01


def look_at(position, target=(0.0, 0.0, 0.0), roll_deg: float = 0.0, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Blender camera_to_world 4x4 (camera looks along its -Z) at ``position`` towards ``target``."""
    p = np.asarray(position, float)
    back = p - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross(np.asarray(up, float), back)
    right /= np.linalg.norm(right)
    cam_up = np.cross(back, right)
    r = np.stack([right, cam_up, back], axis=1)
    a = math.radians(roll_deg)
    roll = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = r @ roll
    m[:3, 3] = p
    return m


def camera_path(n: int, distance: float, seed: int = 7) -> list[np.ndarray]:
    """A smooth orbit in front of the target (15-40 deg off its normal) with some roll and a
    wandering aim point, as a hand-held shot would have."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t = i / max(n - 1, 1)
        az = math.radians(-50 + 100 * t)
        tilt = math.radians(20 + 15 * math.sin(3 * t))
        d = distance * (1 + 0.15 * math.cos(2 * t))
        pos = d * np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
        aim = np.array([0.01 * math.sin(5 * t), -0.01 * math.cos(4 * t), 0.0])
        out.append(look_at(pos, aim, roll_deg=float(rng.uniform(-10, 10))))
    return out


def calibration_path(n: int = 12, distance: float = 0.45, tilt_deg: float = 45.0, seed: int = 3) -> list[np.ndarray]:
    """The views a calibration needs (calibration.ADVICE): the board tilted ``tilt_deg`` towards
    ``n`` directions in turn, rolled, and seen off-centre in different parts of the frame."""
    rng = np.random.default_rng(seed)
    out = []
    tilt = math.radians(tilt_deg)
    for i in range(n):
        az = 2 * math.pi * i / n
        pos = distance * np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
        aim = np.array([0.05 * math.cos(3 * az + 1), 0.05 * math.sin(2 * az + 0.5), 0.0])
        out.append(look_at(pos, aim, roll_deg=float(rng.uniform(-15, 15))))
    return out


def _cycles(scene, width, height, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 1
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def render_target_frames(bpy, texture_png: str, extent_m, poses, out_dir, width=640, height=480,
                         lens_mm=30.0, sensor_mm=36.0, samples=4, shift=(0.0, 0.0)) -> dict:
    """Render the texture (covering ``extent_m`` + margin, centred on the origin in z = 0, its
    top towards +Y) from each Blender camera_to_world in ``poses``; frames as PNG 0001.png...
    Returns the true intrinsics in OpenCV pixel coordinates (checked against tracking with a
    shifted camera: 0.07 deg with this principal point, 2.3 deg with the image centre)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    _cycles(scene, width, height, samples)
    world = compat().new_world("black")
    world.color = (0, 0, 0)
    scene.world = world
    half_w = extent_m[0] / 2 + MARGIN_M
    half_h = extent_m[1] / 2 + MARGIN_M
    mesh = bpy.data.meshes.new("board")
    mesh.from_pydata([(-half_w, -half_h, 0), (half_w, -half_h, 0), (half_w, half_h, 0), (-half_w, half_h, 0)],
                     [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, co in zip(uv.data, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        loop.uv = co
    board = bpy.data.objects.new("board", mesh)
    scene.collection.objects.link(board)
    mat = compat().new_material("board")
    nt = mat.node_tree
    nt.nodes.clear()
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(str(texture_png))
    tex.interpolation = "Closest"
    emit = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(tex.outputs["Color"], emit.inputs["Color"])
    nt.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    mesh.materials.append(mat)
    cam_data = bpy.data.cameras.new("cam")
    cam_data.lens = lens_mm
    cam_data.sensor_width = sensor_mm
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.shift_x, cam_data.shift_y = shift
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    from mathutils import Matrix

    for i, m in enumerate(poses, start=1):
        cam.matrix_world = Matrix(np.asarray(m).tolist())
        scene.render.filepath = str(out_dir / f"{i:04d}.png")
        bpy.ops.render.render(write_still=True)
    f = lens_mm * width / sensor_mm
    # Blender's shift is in image widths: +x moves the view right, so the optical centre moves
    # left in the picture; +y moves the view up, so the centre moves down (to larger OpenCV rows).
    return {"fx": f, "fy": f, "cx": (width - 1) / 2 - shift[0] * width,
            "cy": (height - 1) / 2 + shift[1] * width}


def render_mirror_ball(bpy, hdri_path: str, out_exr: str, size=256, samples=16,
                       camera_to_world=None, ortho_scale=2.5, reflectance=0.8) -> dict:
    """A unit mirror sphere at the origin under ``hdri_path`` (Environment Texture, Blender's
    lat-long convention), seen by an orthographic camera (the ball's radius is
    size/ortho_scale pixels) as a chrome of the given reflectance would be. Float EXR, linear.
    Returns the ball circle in OpenCV pixel coordinates and the camera matrix."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    _cycles(scene, size, size, samples)
    scene.cycles.max_bounces = 2
    world = compat().new_world("probe")
    scene.world = world
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(hdri_path))
    env.interpolation = "Linear"
    bg = nt.nodes.get("Background") or nt.nodes.new("ShaderNodeBackground")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    wout = nt.nodes.get("World Output") or nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(bg.outputs["Background"], wout.inputs["Surface"])
    bpy.ops.mesh.primitive_uv_sphere_add(segments=256, ring_count=128, radius=1.0)
    ball = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    mat = compat().new_material("chrome")
    mnt = mat.node_tree
    mnt.nodes.clear()
    glossy = mnt.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.0
    glossy.inputs["Color"].default_value = (reflectance, reflectance, reflectance, 1)
    mout = mnt.nodes.new("ShaderNodeOutputMaterial")
    mnt.links.new(glossy.outputs["BSDF"], mout.inputs["Surface"])
    ball.data.materials.append(mat)
    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = ortho_scale
    cam_data.clip_end = 100
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    if camera_to_world is None:
        camera_to_world = look_at((0, -10, 0), (0, 0, 0), up=(0, 0, 1))
    from mathutils import Matrix

    cam.matrix_world = Matrix(np.asarray(camera_to_world).tolist())
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.filepath = str(out_exr)
    bpy.ops.render.render(write_still=True)
    return {"cx": (size - 1) / 2, "cy": (size - 1) / 2, "radius": size / ortho_scale,
            "camera_to_world": np.asarray(camera_to_world)}


def tone_curve(x):
    """The known camera response used for the synthetic brackets: a gamma-2.2 shoulder-free
    power law, 8-bit quantised by the caller."""
    return np.clip(x, 0, 1) ** (1 / 2.2)


def make_brackets(radiance: np.ndarray, times, scale: float) -> list[np.ndarray]:
    """8-bit BGR images of linear RGB ``radiance`` at exposure times ``times`` (x ``scale``)."""
    out = []
    for t in times:
        v = tone_curve(radiance * (t * scale))
        out.append(np.ascontiguousarray((np.round(v * 255)).astype(np.uint8)[..., ::-1]))
    return out
