"""The whole chain as a render-farm script drives it: build a scene, save it, bake the probes
(bpy.ops.platelight.bake_probes), apply the SBRDF (bpy.ops.platelight.apply_sbrdf), render with
Cycles, and compare every sphere pixel with a numpy evaluation of the EXR maps the bake wrote.

The numpy side is written here from design.md's equations (Environment Texture lat-long layout,
bilinear lookups, Eq 1-7 for the isotropic C = (-1, -1, 1) of the presets), not from the add-on.

Tolerance: the material is an emission closure showing exactly Lr, the camera is orthographic
and one sample per pixel with a 0.01-pixel box filter hits the pixel centre, so Cycles evaluates
the same bilinear lookups as numpy, in float32 (1e-6). What differs is the normal: the ray hits
a flat facet of a 128 x 64 UV sphere whose smooth normal is interpolated from angle-weighted
vertex normals, not the analytic sphere normal at the pixel centre. Measured with a position
pass, the two differ by at most 0.11 deg on the compared pixels (0.08 deg at the 99th percentile).
The probe maps are tiny and noisy (4 samples, 5.6 deg texels), so that small shift can move a
pixel by ~1 % where neighbouring texels differ a lot. Each pixel is therefore allowed the spread
of the reference over normals tilted by DELTA = 0.15 deg (8 directions) plus 2e-3 relative: a
bound derived per pixel, far below the difference between two frames' maps or two presets
(asserted). Grazing pixels (N.V < 0.25), the silhouette and lookups within one texel row of a
pole (Cycles' lookup wraps over the pole where a lat-long bilinear clamps) are left out; the test
asserts how many pixels remain.
"""
from __future__ import annotations

import importlib
import math
import os
import sys

import numpy as np
import pytest

from sbrdf_reference import fresnel
import support
from bake_scenes import material
from platelight.addon.ibl import irradiance_grid
from platelight.addon.ibl.lobe_tilt import tilt_offset
from sbrdf_scene import noise_free_emission_render
from support import EXT_MODULE
from support import compat

RES_X, RES_Y = 96, 64
ORTHO_SCALE = 3.3                  # the frame spans x in [-1.65, 1.65], z in [-1.1, 1.1]
VIEW = np.array([0.0, -1.0, 0.0])  # surface -> viewer: the camera looks along +Y
MAPS = ("diffuse", "glossy1", "glossy2", "specular")


# --------------------------------------------------------------------------- numpy reference

def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _lookup(img, d):
    """Bilinear Environment Texture lookup of an EXR array (top row first) along directions d."""
    h, w, _ = img.shape
    with np.errstate(invalid="ignore"):
        d = np.nan_to_num(_unit(d))                # off the sphere: looked up, then masked out
    u = np.arctan2(-d[..., 1], d[..., 0]) / (2 * np.pi) + 0.5
    v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5                        # rows counted from the top
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    c0, c1 = x0 % w, (x0 + 1) % w
    r0, r1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    return ((img[r0, c0] * (1 - fx) + img[r0, c1] * fx) * (1 - fy)
            + (img[r1, c0] * (1 - fx) + img[r1, c1] * fx) * fy)


def _pole_distance_rows(d, height):
    d = _unit(d)
    v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
    return np.minimum(v, 1 - v) * height


def sphere_normals(center=(0.0, 0.0, 0.0), radius=1.0):
    """Analytic normal at every pixel centre of the orthographic view (NaN off the sphere)."""
    x = ((np.arange(RES_X) + 0.5) / RES_X - 0.5) * ORTHO_SCALE
    z = (0.5 - (np.arange(RES_Y) + 0.5) / RES_Y) * ORTHO_SCALE * RES_Y / RES_X
    X, Z = np.meshgrid(x - center[0], z - center[2])
    r2 = (X ** 2 + Z ** 2) / radius ** 2
    Y = -np.sqrt(np.where(r2 < 1, 1 - r2, np.nan))
    return np.stack([X / radius, Y, Z / radius], axis=-1)


def sbrdf_reference(maps, p):
    return lambda N: _sbrdf(maps, N, p)


def _sbrdf(maps, N, p):
    """Eq 1-7 for C = (Cx, Cx, Cz) (isotropic: the tangent frame drops out), alpha 1, no emission.
    Returns Lr and the directions looked up (for the pole mask)."""
    assert p["cx"] == p["cy"] and p["alpha"] == 1.0 and p["emission_strength"] == 0.0
    assert p.get("anisotropy", 0.0) == 0.0, "a round lobe: one look-up"
    R = np.broadcast_to(VIEW, N.shape)
    rn = np.sum(R * N, axis=-1, keepdims=True)
    peak = p["cx"] * (R - rn * N) + p["cz"] * rn * N
    g = np.maximum(np.sum(N * peak, axis=-1, keepdims=True), 0.0)
    f = fresnel(p, rn)
    rho_s = np.asarray(p["specular_albedo"]) + (1 - np.asarray(p["specular_albedo"])) * f
    n2 = p["glossiness"] + (1 - p["glossiness"]) * f
    g2 = g + (1 - g) * f
    paper = p.get("paper_falloff", 0.0)
    g2 = 1.0 + paper * (g2 - 1.0)                      # 0: no cosine; 1: the paper's g'
    # the look-up tilt towards N at grazing views (addon/ibl/lobe_tilt.py); the paper: along p
    peak = _unit(peak)
    mu = np.clip(np.sum(N * peak, axis=-1), 0.0, 1.0)
    peak = _unit(peak + (1 - paper) * tilt_offset(n2[..., 0], mu)[..., None] * N)
    if "diffuse" in maps:
        # paper 0: the diffuse layer gets what the specular leaves
        rho_d = np.asarray(p["diffuse_albedo"]) * (paper + (1 - paper) * (1 - rho_s))
        lr = rho_d * _lookup(maps["diffuse"], N)
    else:                                              # a mirror's bake has no diffuse map
        assert not any(p["diffuse_albedo"]), "the diffuse map is needed but was not baked"
        lr = 0.0
    blend = 0.0
    for k, name in enumerate(MAPS):
        weight = np.maximum(0.0, 1.0 - np.abs(3.0 * n2 - k))
        if name in maps:
            blend = blend + weight * _lookup(maps[name], peak)
        else:                                          # a map the bake did not write: black
            assert np.all(weight[np.isfinite(weight)] == 0), f"{name} is needed but was not baked"
    top = max(m.shape[0] for m in maps.values())
    heights = {"N": maps["diffuse"].shape[0] if "diffuse" in maps else top, "peak": top}
    return lr + rho_s * g2 * blend, {"N": (N, heights["N"]), "peak": (peak, heights["peak"])}


DELTA = math.radians(0.15)


def _tilted(N, angle):
    """N tilted by DELTA towards the direction ``angle`` around it."""
    helper = np.where(np.abs(N[..., 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    t1 = _unit(np.cross(N, helper))
    t2 = np.cross(N, t1)
    return _unit(N + math.tan(DELTA) * (math.cos(angle) * t1 + math.sin(angle) * t2))


def compare(image, reference, N):
    """(excess, relative error, pixel count): excess > 0 where a pixel leaves its tolerance.
    ``reference(N)`` returns (Lr, {name: (lookup directions, map height)})."""
    want, dirs = reference(N)
    spread = np.zeros_like(want)
    for k in range(8):
        spread = np.maximum(spread, np.abs(reference(_tilted(N, k * math.pi / 4))[0] - want))
    with np.errstate(invalid="ignore"):
        rn = -N[..., 1]
        mask = (rn > 0.25) & (image[..., 3] > 0.9999)
        for d, height in dirs.values():
            mask &= _pole_distance_rows(np.nan_to_num(d), height) > 1.0
    got, want, spread = image[..., :3][mask], want[mask], spread[mask]
    excess = np.abs(got - want) - (spread + 2e-3 * np.abs(want) + 1e-5)
    rel = np.abs(got - want) / np.maximum(np.abs(want), 0.02)
    return excess, rel, int(mask.sum())


def read_maps(bpy, ob, frame=None):
    from platelight.addon.exr_io import read_exr

    folder = bpy.path.abspath(ob.platelight.probe_dir)
    out = {}
    for name in MAPS:
        path = os.path.join(folder, f"{name}.exr" if frame is None else f"{name}_{frame:04d}.exr")
        if os.path.isfile(path):
            out[name] = read_exr(path, "RGB").astype(np.float64)
    return out


# --------------------------------------------------------------------------- scene

def build_scene(bpy, tmp_path, hdri, cube_enabled=True):
    """Orthographic camera along +Y, world = a bundled HDRI shrunk to 32 x 64, a smooth unit CG
    sphere at the origin, a green CG cube beside it, a red phantom plane under both; saved to
    tmp_path/shot.blend so the maps folder '//platelight_maps' resolves."""
    from platelight.addon.exr_io import read_exr, write_exr

    env = read_exr(hdri, "RGB")
    h, w = env.shape[:2]
    small = env.reshape(32, h // 32, 64, w // 64, 3).mean(axis=(1, 3))
    write_exr(tmp_path / "world.exr", small.astype(np.float32))

    scene = bpy.context.scene
    world = compat().new_world("World")
    scene.world = world
    env_node = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env_node.image = bpy.data.images.load(str(tmp_path / "world.exr"))
    world.node_tree.links.new(env_node.outputs["Color"],
                              world.node_tree.nodes["Background"].inputs["Color"])

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = ORTHO_SCALE
    cam.location = (0.0, -10.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=128, ring_count=64, location=(0, 0, 0))
    sphere = bpy.context.object
    sphere.name = "Sphere"
    bpy.ops.object.shade_smooth()
    sphere.platelight.enabled = True

    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(1.4, -0.6, 0.5))
    cube = bpy.context.object
    cube.name = "Cube"
    cube.data.materials.append(material(bpy, "Green", (0.1, 0.8, 0.1), emission=(0.2, 3.0, 0.2)))
    cube.platelight.enabled = cube_enabled

    bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0, 0, -1.2))
    plane = bpy.context.object
    plane.name = "Floor"
    plane.data.materials.append(material(bpy, "Red", (0.8, 0.05, 0.05)))
    plane.platelight.phantom = True

    render = scene.render
    noise_free_emission_render(scene)
    render.resolution_x, render.resolution_y, render.resolution_percentage = RES_X, RES_Y, 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_mode = "RGBA"
    render.image_settings.color_depth = "32"
    scene.platelight.probe_height = 32             # 64 x 32 probe renders: tiny, 2 shared cores
    scene.platelight.probe_auto_size = False       # every map at Probe Height (test_probe_size.py sizes)
    scene.platelight.probe_samples = 4
    # these tests check the render against the paper's look-ups from the probe centre (the numpy
    # reference above); parallax-corrected look-ups, specular and diffuse, and the sun shaded
    # through the lobe have their own tests (test_parallax.py, test_irradiance_grid.py,
    # test_sun_lobe_render.py)
    scene.platelight.probe_parallax = False
    scene.platelight.probe_diffuse_parallax = False
    scene.platelight.probe_sun_lobe = False        # the sun through the lobe: test_sun_lobe_render.py
    scene.platelight.glossy_lobes = "phong"        # the view-dependent ladder: test_view_lobe_render.py
    scene.frame_set(1)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    return scene, sphere, cube, plane


def select_only(bpy, ob):
    for other in bpy.context.view_layer.objects:
        other.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob


def render(bpy, tmp_path, name):
    from platelight.addon.exr_io import read_exr

    scene = bpy.context.scene
    scene.render.filepath = str(tmp_path / name)
    bpy.ops.render.render(write_still=True)
    return read_exr(tmp_path / name, "RGBA").astype(np.float64)


def open_on_farm(bpy, tmp_path):
    """Save the shot and open a copy of it (and its world image) in tmp_path/farm, where no maps
    folder exists, as a farm node would; returns that folder."""
    import shutil

    bpy.ops.wm.save_mainfile()
    farm = tmp_path / "farm"
    farm.mkdir()
    shutil.copy(tmp_path / "shot.blend", farm / "shot.blend")
    shutil.copy(tmp_path / "world.exr", farm / "world.exr")
    bpy.ops.wm.open_mainfile(filepath=str(farm / "shot.blend"))
    assert not (farm / "platelight_maps").exists()
    return farm


def sbrdf_params(bpy, ob):
    from dataclasses import asdict

    sm = sys.modules[f"{EXT_MODULE}.node_groups.sbrdf_material"]
    return asdict(sm.read_params(ob.active_material))


def assert_matches(image, reference, N, min_pixels=600):
    excess, rel, count = compare(image, reference, N)
    assert count >= min_pixels, f"only {count} comparable pixels"
    print(f"pixels {count}: relative error median {np.median(rel):.1e}, "
          f"p99 {np.quantile(rel, 0.99):.1e}, max {rel.max():.1e}; worst excess {excess.max():.1e}")
    assert excess.max() <= 0.0
    assert np.median(rel) < 2e-3
    return rel


def data_counts(bpy):
    """The file's own (not library-linked) images, node groups and materials."""
    return {kind: sorted(d.name for d in getattr(bpy.data, kind) if d.library is None)
            for kind in ("images", "node_groups", "materials")}


# --------------------------------------------------------------------------- tests

def test_bake_apply_render_matches_the_baked_maps(bpy_clean, tmp_path, studio_hdris):
    """1. bake (all objects) -> apply chrome / marble -> Cycles render == numpy(maps)."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["forest"])
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    assert sphere.platelight.probe_dir == "//platelight_maps/Sphere/"
    assert cube.platelight.probe_dir == "//platelight_maps/Cube/"
    assert plane.platelight.probe_dir == ""                      # phantoms get no probe
    maps = read_maps(bpy, sphere)
    assert sorted(maps) == sorted(MAPS)                           # no SBRDF yet: all four
    # The red phantom tints the lower half of the sphere's diffuse map (colour bleeding).
    d = maps["diffuse"]
    below = d[-3:].mean(axis=(0, 1))
    assert below[0] > 1.5 * below[1]

    N = sphere_normals()
    select_only(bpy, sphere)
    images = {}
    for preset in ("chrome", "marble"):
        assert bpy.ops.platelight.apply_sbrdf(preset=preset) == {"FINISHED"}
        p = sbrdf_params(bpy, sphere)
        images[preset] = render(bpy, tmp_path, f"{preset}.exr")
        assert_matches(images[preset], sbrdf_reference(maps, p), N)
    # The chrome sphere and the marble one really differ (the comparison is not vacuous).
    inside = np.isfinite(N[..., 0])
    assert np.abs(images["chrome"] - images["marble"])[inside].max() > 0.2

    # Move the cube and bake again, without re-applying: the material follows the new maps.
    cube.location = (-1.4, -0.6, 0.5)
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    new_maps = read_maps(bpy, sphere)
    assert np.abs(new_maps["specular"] - maps["specular"]).max() > 0.1
    moved = render(bpy, tmp_path, "moved.exr")
    assert_matches(moved, sbrdf_reference(new_maps, p), N)


def test_frame_range_bake_binds_the_sequence(bpy_clean, tmp_path, studio_hdris):
    """2. A moving emissive cube, frames 1-2: diffuse_0001.exr..., frame 2 renders frame-2 maps;
    also after a single-frame bake and an applied material (the material follows the re-bake)."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["interior"],
                                             cube_enabled=False)
    cube.location = (1.4, -0.6, 0.5)
    cube.keyframe_insert("location", frame=1)
    cube.location = (-1.4, -0.6, -0.5)
    cube.keyframe_insert("location", frame=2)
    scene.frame_set(1)
    bpy.ops.wm.save_mainfile()

    # A preview bake of the current frame, then the material, then the frame-range bake.
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    assert bpy.ops.platelight.bake_probes(all_objects=True, frame_start=1, frame_end=2) == {"FINISHED"}
    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    files = sorted(f for f in os.listdir(folder) if f.endswith(".exr"))
    # Marble (n = 0.7 with Fresnel) reads diffuse, glossy2 and specular: only those, per frame.
    # (and the distance map of its parallax-corrected look-ups)
    assert files == [f"{name}_{frame:04d}.exr" for name in ("diffuse", "distance", "glossy2", "specular")
                     for frame in (1, 2)]
    assert scene.frame_current == 1

    N = sphere_normals()
    p = sbrdf_params(bpy, sphere)
    maps = {f: read_maps(bpy, sphere, frame=f) for f in (1, 2)}
    # The cube moved from the right to the left: the maps differ a lot.
    assert np.abs(maps[1]["diffuse"] - maps[2]["diffuse"]).max() > 0.1
    # Render the range as a farm node does (an animation render: the sequence images advance).
    from platelight.addon.exr_io import read_exr

    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "anim_####")
    bpy.ops.render.render(animation=True)
    images = {f: read_exr(tmp_path / f"anim_{f:04d}.exr", "RGBA").astype(np.float64) for f in (1, 2)}
    for frame in (1, 2):
        assert_matches(images[frame], sbrdf_reference(maps[frame], p), N)
    # Frame 2's render is not frame 1's maps (the comparison can tell the frames apart).
    excess, rel, _ = compare(images[2], sbrdf_reference(maps[1], p), N)
    assert excess.max() > 0.05 and rel.max() > 0.1

    # No image is left pointing at a map file the range bake replaced.
    missing = [im.name for im in bpy.data.images if im.source in {"FILE", "SEQUENCE"}
               and not os.path.isfile(bpy.path.abspath(im.filepath))]
    assert missing == []

    # Re-applying after the range bake binds the same sequence (a script that applies last).
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    scene.frame_set(2)
    again = render(bpy, tmp_path, "frame2b.exr")
    np.testing.assert_allclose(again, images[2], atol=1e-6)


def test_rerun_does_not_duplicate_and_bad_input_changes_nothing(bpy_clean, tmp_path, studio_hdris,
                                                                capfd):
    """3. bake + apply twice: no new images, node groups or materials; failing operators
    report, return CANCELLED and leave scene, data and maps as they were."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["courtyard"])
    select_only(bpy, sphere)

    def run(preset):
        assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
        assert bpy.ops.platelight.apply_sbrdf(preset=preset) == {"FINISHED"}

    run("chrome")
    run("chrome")        # now baked for the chrome material: specular only (images dropped)
    steady = data_counts(bpy)
    run("chrome")
    assert data_counts(bpy) == steady
    assert bpy.ops.platelight.bake_probes(all_objects=True, force=True) == {"FINISHED"}
    assert data_counts(bpy) == steady
    paths = [bpy.path.abspath(im.filepath) for im in bpy.data.images if im.source != "GENERATED"]
    assert len(paths) == len(set(paths)) and all(os.path.isfile(p) for p in paths)
    assert sum(1 for g in bpy.data.node_groups if g.name.startswith("PlateLight Probe")) == 1
    assert sum(1 for g in bpy.data.node_groups if g.name == "PlateLight SBRDF") == 1
    assert sorted(m.name for m in sphere.data.materials) == ["Sphere SBRDF"]

    # Marble reads diffuse and glossy2 too, which the chrome bake did not write: apply says so,
    # the next bake writes them and the material follows.
    capfd.readouterr()
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    assert "diffuse, glossy2 map(s)" in capfd.readouterr().out
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    assert sorted(f for f in os.listdir(folder) if f.endswith(".exr")) == [
        "diffuse.exr", "distance.exr", "glossy2.exr", "specular.exr"]
    probe = sphere.active_material.node_tree.nodes["PlateLight Probe"].node_tree
    bound = sorted({n.image.name for n in probe.nodes if getattr(n, "image", None) is not None
                    and n.image.name != "PlateLight Unbaked Map"})
    assert bound == ["diffuse.exr", "distance.exr", "glossy2.exr", "specular.exr"]
    capfd.readouterr()
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    assert "bake the probes again" not in capfd.readouterr().out

    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    maps_before = {f: os.path.getmtime(os.path.join(folder, f)) for f in os.listdir(folder)}

    def state():
        return (data_counts(bpy), sphere.platelight.probe_dir, sphere.active_material.name,
                sphere.platelight.probe_status, scene.frame_current, scene.camera.name,
                tuple(sphere.location), scene.render.resolution_x)

    before = state()
    # In a script an operator's ERROR report (with CANCELLED) arrives as a RuntimeError.
    # A range that ends before it starts.
    with pytest.raises(RuntimeError, match="ends .2. before it starts .3."):
        bpy.ops.platelight.bake_probes(all_objects=True, frame_start=3, frame_end=2)
    assert state() == before
    # A maps folder that cannot be created (a file stands where the folder should be).
    (tmp_path / "blocked").write_text("not a folder")
    scene.platelight.maps_dir = str(tmp_path / "blocked" / "maps")
    with pytest.raises(RuntimeError, match="maps folder"):
        bpy.ops.platelight.bake_probes(all_objects=True, force=True)
    scene.platelight.maps_dir = ""
    assert state() == before
    # No camera.
    camera = scene.camera
    scene.camera = None
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.platelight.bake_probes(all_objects=True, force=True)
    scene.camera = camera
    assert state() == before
    # apply_sbrdf on an object linked from a library (read-only): one sentence, nothing created.
    library = tmp_path / "props.blend"
    bpy.data.libraries.write(str(library), {cube.data})
    with bpy.data.libraries.load(str(library), link=True) as (_src, dst):
        dst.meshes = [cube.data.name]
    linked = bpy.data.objects.new("LinkedProp", dst.meshes[0])
    scene.collection.objects.link(linked)
    select_only(bpy, linked)
    with pytest.raises(RuntimeError, match="materials of LinkedProp live in its data .* linked"):
        bpy.ops.platelight.apply_sbrdf(preset="chrome")
    assert state() == before
    mesh = linked.data
    bpy.data.objects.remove(linked)
    bpy.data.libraries.remove(mesh.library)
    # apply_sbrdf on something that cannot hold a material: poll refuses, nothing changes.
    empty = bpy.data.objects.new("Empty", None)
    scene.collection.objects.link(empty)
    select_only(bpy, empty)
    assert not bpy.ops.platelight.apply_sbrdf.poll()
    bpy.data.objects.remove(empty)
    assert state() == before
    assert {f: os.path.getmtime(os.path.join(folder, f)) for f in os.listdir(folder)} == maps_before


def test_farm_split_bake_renders_every_frame(bpy_clean, tmp_path, studio_hdris):
    """The artist applies the SBRDF and saves; two farm nodes bake halves of the range with the
    CLI, the first to finish saves the .blend (it knows only its own frames); a render node
    renders frame 3, from the half the saving node never saw."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["interior"],
                                             cube_enabled=False)
    for frame, y in ((1, -1.5), (4, 1.5)):        # beside the sphere, from front to back
        cube.location = (1.4, y, 0.5)
        cube.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="chrome") == {"FINISHED"}
    p = sbrdf_params(bpy, sphere)
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_mainfile()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "artist.blend"), copy=True)  # never baked
    first = support.run_cli("bake", blend, "--frames", "1-4", "--part", "1/2", "--save")
    assert first.returncode == 0, first.stderr
    second = support.run_cli("bake", blend, "--frames", "1-4", "--part", "2/2")
    assert second.returncode == 0, second.stderr

    bpy.ops.wm.open_mainfile(filepath=str(blend))
    sphere = bpy.data.objects["Sphere"]
    scene = bpy.context.scene
    N = sphere_normals()
    images = {}
    for frame in (3, 2):
        scene.frame_set(frame)
        images[frame] = render(bpy, tmp_path, f"farm{frame}.exr")
        assert_matches(images[frame], sbrdf_reference(read_maps(bpy, sphere, frame=frame), p), N)
    excess, _, _ = compare(images[3], sbrdf_reference(read_maps(bpy, sphere, frame=2), p), N)
    assert excess.max() > 0.05                     # frame 2's maps would be seen as wrong

    # A render node given the artist's file (no node saved into it): one refresh finds the
    # maps in the object's default folder and frame 3 renders right.
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "artist.blend"))
    sphere = bpy.data.objects["Sphere"]
    assert sphere.platelight.probe_dir == ""
    assert bpy.ops.platelight.refresh_sbrdf_maps() == {"FINISHED"}
    bpy.context.scene.frame_set(3)
    sphere.platelight.probe_dir = "//platelight_maps/Sphere/"     # only so read_maps finds them
    image = render(bpy, tmp_path, "artist3.exr")
    assert_matches(image, sbrdf_reference(read_maps(bpy, sphere, frame=3), p), N)


def test_world_only_object_shares_the_world_maps(bpy_clean, tmp_path, studio_hdris):
    """A sphere alone under the world: the bake points it at _world/, the material applied
    before the bake follows there without a second probe group, and renders those maps."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["sunrise"])
    for ob in (cube, plane):
        bpy.data.objects.remove(ob)
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    assert sphere.platelight.probe_dir == "//platelight_maps/_world/"
    assert [g.name for g in bpy.data.node_groups if g.name.startswith("PlateLight Probe")] == [
        "PlateLight Probe World"]
    maps, p = read_maps(bpy, sphere), sbrdf_params(bpy, sphere)
    assert maps["diffuse"].shape == (16, 32, 3)        # world maps: full default sizes
    image = render(bpy, tmp_path, "world_only.exr")
    assert_matches(image, sbrdf_reference(maps, p), sphere_normals())


def test_packed_maps_render_after_the_blend_moves(bpy_clean, tmp_path, studio_hdris):
    """Pack Maps on: the .blend alone (no maps folder next to it) renders the same on a farm node."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["city"])
    scene.platelight.pack_maps = True
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="polished_paint") == {"FINISHED"}
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    maps, p, N = read_maps(bpy, sphere), sbrdf_params(bpy, sphere), sphere_normals()
    farm = open_on_farm(bpy, tmp_path)
    image = render(bpy, farm, "farm.exr")
    assert_matches(image, sbrdf_reference(maps, p), N)


def test_diffuse_object_gets_only_the_diffuse_map(bpy_clean, tmp_path, studio_hdris):
    """4. A purely diffuse SBRDF (rho_s = 0, Fresnel off) bakes diffuse.exr alone, and the
    material renders rho_d * diffuse_map(N) with the other maps absent."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["sunset"])
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    node = sphere.active_material.node_tree.nodes["PlateLight SBRDF"]
    node.inputs["Diffuse Albedo"].default_value = (0.7, 0.5, 0.3, 1.0)
    node.inputs["Specular Albedo"].default_value = (0.0, 0.0, 0.0, 1.0)
    node.inputs["Fresnel Falloff"].default_value = 0.0
    node.inputs["Glossiness"].default_value = 0.0
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    assert sorted(f for f in os.listdir(folder) if f.endswith(".exr")) == ["diffuse.exr"]

    maps = read_maps(bpy, sphere)
    N = sphere_normals()
    image = render(bpy, tmp_path, "diffuse.exr")
    height = maps["diffuse"].shape[0]

    def reference(normals):   # the brief's formula: rho_d * diffuse_map(N)
        return np.array([0.7, 0.5, 0.3]) * _lookup(maps["diffuse"], normals), {"N": (normals, height)}

    assert_matches(image, reference, N)


def _image_lookup(img, x, y):
    """Bilinear Image Texture lookup (Linear, Extend) of an EXR array (top row first) at image
    coordinates (x, y) in [0, 1], y up: Blender's texel centres at (i + 0.5) / size."""
    h, w, _ = img.shape
    px, py = x * w - 0.5, (1.0 - y) * h - 0.5
    x0, y0 = np.floor(px).astype(int), np.floor(py).astype(int)
    fx, fy = (px - x0)[..., None], (py - y0)[..., None]
    c0, c1 = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    r0, r1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    return ((img[r0, c0] * (1 - fx) + img[r0, c1] * fx) * (1 - fy)
            + (img[r1, c0] * (1 - fx) + img[r1, c1] * fx) * fy)


@pytest.mark.parametrize("with_sun", [False, True])
def test_diffuse_parallax_renders_the_irradiance_grid_blend(bpy_clean, tmp_path, studio_hdris, with_sun):
    """Diffuse Parallax on: the bake writes the grid atlas and its record, and the render is
    rho_d times the trilinear blend of the eight grid maps around the shading point, each read
    along N from its tile of the atlas (numpy from the record: irradiance_grid.trilinear and
    atlas_uv, and an Image Texture's bilinear filter written here). Under a sun (one hot texel
    of the shrunk world) the grid is baked without it and the sun's Lambert term is added
    (sun_lobe.lambert); a grid that holds the sun (a record without "sunless") is not read
    beside that term."""
    import json

    from platelight.addon import names as pl_names
    from platelight.addon.exr_io import read_exr
    from platelight.addon.ibl import irradiance_grid as ig
    from platelight.addon.ibl import sun_lobe

    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["sunset"])
    if with_sun:            # the shrunk world at 8 times its size, a small hot disc 50 degrees up
        from platelight.addon.exr_io import write_exr

        world = read_exr(tmp_path / "world.exr").repeat(8, axis=0).repeat(8, axis=1)
        world[70:73, 200:203] = 2000.0
        write_exr(tmp_path / "world.exr", world)
        bpy.data.images["world.exr"].reload()
        scene.platelight.probe_sun_lobe = True
    matte_grid_sphere(bpy, scene, sphere)
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    record = json.loads(open(os.path.join(folder, "bake.json")).read())
    sun = sun_lobe.from_record(record)
    assert (sun is not None) == with_sun
    assert sorted(f for f in os.listdir(folder) if f.endswith(".exr")) == \
        sorted(["diffuse.exr", ig.grid_filename(), "distance.exr"] + (["diffuse_sunless.exr"] if sun else []))
    grid = record[ig.RECORD_KEY]
    assert grid["sunless"] == (sun is not None)
    atlas = read_exr(os.path.join(folder, ig.grid_filename()), "RGB").astype(np.float64)
    n, height = grid["points"], grid["height"]
    assert n == ig.DEFAULT_POINTS and atlas.shape == (height + 2 * ig.PAD, n ** 3 * (2 * height + 2 * ig.PAD), 3)
    # the box is the unit sphere's, inset
    np.testing.assert_allclose(grid["hi"], [1 - ig.INSET * 2] * 3, atol=0.01)
    np.testing.assert_allclose(grid["lo"], [-1 + ig.INSET * 2] * 3, atol=0.01)

    image = render(bpy, tmp_path, "grid.exr")
    assert_matches(image, grid_reference(folder, record, sun), sphere_normals())
    if sun is not None:
        del record[ig.RECORD_KEY]["sunless"]
        open(os.path.join(folder, "bake.json"), "w").write(json.dumps(record))
        probe_maps = importlib.import_module(f"{support.EXT_MODULE}.node_groups.probe_maps")
        probe_maps.set_parallax()
        group = bpy.data.node_groups[pl_names.PROBE_GROUP_PREFIX + "Sphere"]
        assert group.nodes[pl_names.DIFFUSE_PARALLAX_NODE].outputs[0].default_value == 0.0
        return
    # not the paper's centre look-up: the lower half sees the red floor from close by
    centre = np.array(MATTE_ALBEDO) * _lookup(read_maps(bpy, sphere)["diffuse"], sphere_normals())
    inside = np.isfinite(centre[..., 0])
    assert np.abs(image[..., :3] - centre)[inside].max() > 0.02


def test_a_moving_object_reads_each_frames_own_grid(bpy_clean, tmp_path, studio_hdris):
    """Over a baked sequence in which the object moves, the probe group keys each frame's grid box
    (its bake record's): on the last frame the render is that frame's grid blend as numpy reads
    it, where the first frame's box, 0.6 m away, would clamp every shading point to its face."""
    from platelight.addon import names as pl_names
    from platelight.addon.bake.layout import read_record

    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["sunset"], cube_enabled=False)
    matte_grid_sphere(bpy, scene, sphere)
    scene.platelight.probe_sun_lobe = False
    for frame, location in ((1, (0.6, 0.0, 0.0)), (2, (0.0, 0.0, 0.0))):
        sphere.location = location
        sphere.keyframe_insert("location", frame=frame)
    assert bpy.ops.platelight.bake_probes(all_objects=True, frame_start=1, frame_end=2) == {"FINISHED"}
    folder = bpy.path.abspath(sphere.platelight.probe_dir)
    group = bpy.data.node_groups[pl_names.PROBE_GROUP_PREFIX + "Sphere"]
    assert group.nodes[pl_names.DIFFUSE_PARALLAX_NODE].outputs[0].default_value == 1.0
    lo = group.nodes[pl_names.GRID_LO_NODE].inputs
    for frame in (1, 2):
        scene.frame_set(frame)
        grid = read_record(folder, frame)[irradiance_grid.RECORD_KEY]
        assert [lo[axis].default_value for axis in "XYZ"] == pytest.approx(grid["lo"], abs=1e-5)
    image = render(bpy, tmp_path, "grid_2.exr")
    assert_matches(image, grid_reference(folder, read_record(folder, 2), None, frame=2), sphere_normals())


MATTE_ALBEDO = (0.7, 0.5, 0.3)


def matte_grid_sphere(bpy, scene, sphere):
    """The sphere's SBRDF a matte MATTE_ALBEDO with Diffuse Parallax on: the render is the
    albedo times the grid blend (grid_reference)."""
    scene.platelight.probe_diffuse_parallax = True
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    node = sphere.active_material.node_tree.nodes["PlateLight SBRDF"]
    node.inputs["Diffuse Albedo"].default_value = (*MATTE_ALBEDO, 1.0)
    node.inputs["Specular Albedo"].default_value = (0.0, 0.0, 0.0, 1.0)
    node.inputs["Fresnel Falloff"].default_value = 0.0
    node.inputs["Glossiness"].default_value = 0.0


def grid_reference(folder, record, sun, frame=None):
    """numpy's render of matte_grid_sphere's unit sphere at the origin (the shading point is N):
    the trilinear blend of the record's grid maps around it (irradiance_grid.trilinear, atlas_uv,
    an Image Texture's bilinear filter) read along N, plus the sun's Lambert term."""
    from platelight.addon.exr_io import read_exr
    from platelight.addon.ibl import sun_lobe

    ig = irradiance_grid
    grid = record[ig.RECORD_KEY]
    n, height = grid["points"], grid["height"]
    atlas = read_exr(os.path.join(folder, ig.grid_filename(frame)), "RGB").astype(np.float64)

    def reference(normals):
        points = np.nan_to_num(normals)
        tiles, weights = ig.trilinear(np.array(grid["lo"]), np.array(grid["hi"]), n, points)
        d = _unit(points + (points == 0).all(axis=-1, keepdims=True))
        u = np.arctan2(-d[..., 1], d[..., 0]) / (2 * np.pi) + 0.5
        v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
        total = 0.0
        for k in range(8):
            x, y = ig.atlas_uv(tiles[..., k], u, v, n ** 3, height)
            total = total + weights[..., k:k + 1] * _image_lookup(atlas, x, y)
        if sun is not None:
            total = total + sun_lobe.lambert(np.nan_to_num(normals), sun)
        return np.array(MATTE_ALBEDO) * total, {"N": (normals, height)}

    return reference


def test_packed_parallax_look_ups_render_after_the_blend_moves(bpy_clean, tmp_path, studio_hdris):
    """Pack Maps with both parallax corrections on: the distance map and the irradiance grid
    travel in the .blend too, so a farm node without the maps folder renders what the
    workstation does (unpacked, the grid would read black with its switch on)."""
    bpy = bpy_clean
    scene, sphere, cube, plane = build_scene(bpy, tmp_path, studio_hdris["city"])
    scene.platelight.pack_maps = True
    scene.platelight.probe_parallax = True
    scene.platelight.probe_diffuse_parallax = True
    select_only(bpy, sphere)
    assert bpy.ops.platelight.apply_sbrdf(preset="marble") == {"FINISHED"}
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    packed = {im.name.rsplit("/", 1)[-1] for im in bpy.data.images if im.packed_file is not None}
    assert {"diffuse_grid.exr", "distance.exr"} <= packed
    here = render(bpy, tmp_path, "here.exr")
    farm = open_on_farm(bpy, tmp_path)
    there = render(bpy, farm, "farm.exr")
    inside = np.isfinite(sphere_normals()[..., 0])
    assert np.abs(here - there)[inside].max() < 1e-5
