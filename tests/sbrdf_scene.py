"""Shared helpers for the SBRDF Blender tests: synthetic maps, a grid of spheres seen by an
orthographic camera, and a float render read back (no PlateLight code involved here)."""
from __future__ import annotations

import math
import pathlib

import numpy as np

from platelight.addon.exr_io import read_exr, write_exr
from platelight.addon.ibl import lights
from support import compat

MAP_HEIGHTS = {"diffuse": 16, "glossy1": 32, "glossy2": 64, "specular": 128}
VIEW = np.array([0.0, -1.0, 0.0])     # surface -> viewer for a camera looking along +Y
# The sun the sun and ladder render tests write into a write_sunlit_probe folder's record.
SUN = lights.DirectionalLight(np.array([0.5, -0.6, 0.7]) / np.linalg.norm([0.5, -0.6, 0.7]),
                              np.array([5.0, 4.0, 3.0]), 0.02, True)


def synthetic_maps(seed: int = 0) -> dict:
    """Four maps with a different smooth pattern each, plus texel noise (so a wrong lookup
    direction, map or blend weight shows), all values in [0.15, 1.3]."""
    rng = np.random.default_rng(seed)
    maps = {}
    for k, (name, h) in enumerate(MAP_HEIGHTS.items()):
        w = 2 * h
        u = (np.arange(w) + 0.5) / w
        v = 1.0 - (np.arange(h) + 0.5) / h
        az = 2 * np.pi * (u - 0.5)
        el = np.pi * (v - 0.5)
        A, E = np.meshgrid(az, el)
        img = np.empty((h, w, 3), np.float32)
        img[..., 0] = 0.7 + 0.3 * np.sin((k + 1) * A + 0.5 * k) * np.cos(E)
        img[..., 1] = 0.7 + 0.3 * np.cos(2 * E + k) * np.cos(A)
        img[..., 2] = 0.7 + 0.3 * np.sin(3 * A - k) * np.sin(E + 0.3)
        img += rng.uniform(-0.1, 0.1, img.shape).astype(np.float32)
        img *= 1.0 + 0.15 * k
        maps[name] = img
    return maps


def write_maps(folder: pathlib.Path, maps: dict, frame: int | None = None) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, img in maps.items():
        fname = f"{name}.exr" if frame is None else f"{name}_{frame:04d}.exr"
        write_exr(folder / fname, img)


def noise_free_emission_render(scene):
    """Cycles settings under which an emission-only material renders its exact value: one
    sample, a box filter narrower than a pixel (no neighbour blur), no bounces, no denoiser."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01
    scene.cycles.max_bounces = 0
    scene.render.film_transparent = True


def setup_scene(bpy, count: int, size: int = 48):
    """``count`` unit spheres in a row-major grid, an orthographic camera along +Y; returns the
    sphere objects and the (columns, rows) of the grid."""
    cols = min(count, 4)
    rows = math.ceil(count / cols)
    scene = bpy.context.scene
    noise_free_emission_render(scene)
    scene.render.resolution_x = cols * size
    scene.render.resolution_y = rows * size
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.2 * cols
    cam_data.sensor_fit = "HORIZONTAL"      # the scale spans the columns even when rows > cols
    cam = bpy.data.objects.new("Cam", cam_data)
    cam.location = (0.0, -10.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    spheres = []
    for i in range(count):
        r, c = divmod(i, cols)
        bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0,
                                             location=(2.2 * (c - (cols - 1) / 2), 0.0,
                                                       2.2 * ((rows - 1) / 2 - r)))
        ob = bpy.context.object
        ob.name = f"Sphere{i}"
        bpy.ops.object.shade_smooth()
        spheres.append(ob)
    return spheres, (cols, rows)


def render(bpy, path: pathlib.Path) -> np.ndarray:
    scene = bpy.context.scene
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path, "RGBA")


def position_material(bpy):
    """Emission showing object coordinates as 0.25 * P + 0.5 (to read P back per pixel)."""
    mat = compat().new_material("PositionPass")
    nt = mat.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    vm = nt.nodes.new("ShaderNodeVectorMath")
    vm.operation = "MULTIPLY_ADD"
    vm.inputs[1].default_value = (0.25, 0.25, 0.25)
    vm.inputs[2].default_value = (0.5, 0.5, 0.5)
    em = nt.nodes.new("ShaderNodeEmission")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(tc.outputs["Object"], vm.inputs[0])
    nt.links.new(vm.outputs[0], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    return mat


def interior_mask(alpha: np.ndarray) -> np.ndarray:
    """Pixels fully covered and whose 8 neighbours are too (away from silhouettes)."""
    full = alpha >= 0.9999
    m = full.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            m &= np.roll(np.roll(full, dy, 0), dx, 1)
    m[0, :] = m[-1, :] = m[:, 0] = m[:, -1] = False
    return m


def render_cases(bpy, folder: pathlib.Path, cases: dict) -> dict:
    """Spheres shaded by the SBRDF with each case's parameters, bound to the probe ``folder``
    (maps already written), with the exact sphere normal; the render and a position pass."""
    import dataclasses

    from bl_ext.dev.platelight.node_groups import sbrdf_material as sm
    from platelight.addon.material.params import SBRDFParams

    spheres, (cols, rows) = setup_scene(bpy, len(cases))
    for ob, values in zip(spheres, cases.values()):
        ob.platelight.probe_dir = str(folder)
        mat = sm.apply_sbrdf_material(ob, params=dataclasses.replace(SBRDFParams(), **values))
        # Exact sphere normal (object coordinates), so the reference knows N per pixel.
        tc = mat.node_tree.nodes.new("ShaderNodeTexCoord")
        mat.node_tree.links.new(tc.outputs["Object"], sm.sbrdf_node(mat).inputs["Normal"])
    image = render(bpy, folder.parent / "sbrdf.exr")
    pos_mat = position_material(bpy)
    for ob in spheres:
        ob.material_slots[0].material = pos_mat
    pos = render(bpy, folder.parent / "position.exr")
    return dict(image=image, pos=pos, cols=cols, size=image.shape[0] // rows)


def case_tile(rendered: dict, index: int):
    """(rendered colour, object-space position, interior mask) of case ``index``'s sphere."""
    r, c = divmod(index, rendered["cols"])
    s = rendered["size"]
    tile = np.s_[r * s:(r + 1) * s, c * s:(c + 1) * s]
    image, pos = rendered["image"][tile], rendered["pos"][tile]
    mask = interior_mask(pos[..., 3]) & interior_mask(image[..., 3])
    return image[..., :3].astype(np.float64), (pos[..., :3].astype(np.float64) - 0.5) * 4.0, mask


def worst_relative_error(rendered: dict, maps: dict, cases: dict, case: str, **reference) -> float:
    """The worst relative error of case ``case``'s sphere in ``rendered`` (render_cases) against
    the numpy reference (sbrdf_reference.sbrdf with ``maps`` and ``reference``: sun, sunless,
    rungs), over its interior away from the poles' wrapped rows."""
    import dataclasses

    import sbrdf_reference as ref
    from platelight.addon.material.params import SBRDFParams

    got, P, mask = case_tile(rendered, list(cases).index(case))
    params = dataclasses.asdict(dataclasses.replace(SBRDFParams(), **cases[case]))
    want, dirs = ref.sbrdf(P, VIEW, maps, params, **reference)
    for d in dirs:
        mask &= ~ref.near_pole(d, maps)
    assert mask.sum() > 200, "too few pixels compared"
    return float((np.abs(got - want) / np.maximum(np.abs(want), 1e-2))[mask].max())


def render_cases_in_new_scene(bpy, folder: pathlib.Path, cases: dict, **settings) -> dict:
    """render_cases in an empty factory scene whose scene.platelight ``settings`` are set first
    (e.g. glossy_lobes="phong"): each call binds the probe group afresh under those settings."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    for name, value in settings.items():
        setattr(bpy.context.scene.platelight, name, value)
    return render_cases(bpy, folder, cases)


def write_sunlit_probe(folder: pathlib.Path) -> tuple[dict, dict]:
    """A probe folder with the four synthetic maps and different synthetic sunless maps (as a bake
    that split a sun writes them; the record is the caller's): (maps, sunless maps)."""
    from platelight.addon.ibl import sun_lobe

    maps = synthetic_maps()
    sunless = {k: v for k, v in synthetic_maps(seed=1).items() if k in sun_lobe.SUNLESS_MAPS}
    write_maps(folder, maps)
    for name, image in sunless.items():
        write_exr(folder / sun_lobe.sunless_filename(name), image)
    return maps, sunless

