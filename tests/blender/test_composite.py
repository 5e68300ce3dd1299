"""Differential compositing in headless Cycles: the plate passes through bit-exact where nothing
touches it, phantoms hide CG behind them, a sun's shadow falls where the sun direction says, and
the compositor group computes the formulas of node_groups/composite.py (numpy reference)."""
import importlib
import math
import pathlib

import numpy as np
import pytest

import support
from support import compat
from composite_scene import (H, SPHERE_C, SPHERE_R, W, add_camera, add_plane, add_sphere, add_sun,  # noqa: F401
                             build_scene, grey_world, ground_points, in_shadow, inner, metal_material, ops_module,
                             principled_material, random_plate, render, render_with_passes, sphere_hit)
from platelight.addon.exr_io import read_exr, write_exr
from platelight.addon.ibl.equirect import texel_directions

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


@pytest.mark.parametrize("method,denoise,ratio", [("CATCHER", False, True), ("CATCHER", True, True),
                                                  ("DIFFERENTIAL", True, True), ("DIFFERENTIAL", False, False)])
def test_plate_unchanged_wherever_render_says_untouched_full_light_paths(bpy_clean, tmp_path, method, denoise,
                                                                         ratio):
    """With every light path on (bounces, world light), each pixel that the CG does not reach
    (alpha 0 and shadow ratio exactly 1) is bit-exact, and that is most of the frame; the
    optional denoiser does not touch those pixels."""
    bpy = bpy_clean
    scene, plate = build_scene(bpy, tmp_path, method)
    assert bpy.ops.platelight.setup_composite(method=method, samples=16, denoise_shadows=denoise,
                                              ratio_form=ratio) == {"FINISHED"}
    # adaptive sampling stops clean pixels, except where two renders' difference must cancel
    assert scene.cycles.use_adaptive_sampling == (method != "DIFFERENTIAL")
    out, passes = render_with_passes(bpy, scene, tmp_path)
    # Shadows is the ratio, or (With − Without) + 1 in the additive form: 1 means untouched
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


@pytest.mark.parametrize("method", ["CATCHER", "DIFFERENTIAL"])
def test_sun_shadow_falls_where_the_probe_sun_says(bpy_clean, tmp_path, method):
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
    assert bpy.ops.platelight.setup_composite(method=method, samples=8) == {"FINISHED"}
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
    tree = compat().new_compositor_tree(scene, "Group Test")
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
    tree.links.new(node.outputs["Image"], compat().composite_output(tree))
    return tree


@pytest.mark.parametrize("form", ["ratio", "additive", "tone", "grain"])
def test_group_matches_numpy_reference(bpy_clean, tmp_path, form):
    """The compositor group against the formulas written out in numpy, on random images."""
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 32, 16
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    ops_module("common").set_plate_colour_management(scene)
    rng = np.random.default_rng(3)
    shape = (16, 32)
    plate = rng.uniform(0.05, 2.0, shape + (3,))
    alpha = rng.choice([0.0, 0.3, 1.0], shape)[..., None]
    cg = rng.uniform(0, 3, shape + (3,)) * alpha
    without = rng.uniform(0.0, 1.5, shape + (3,))
    without[0, :4] = 0.0  # division guard
    with_ = without * rng.uniform(0.2, 1.8, shape + (3,))
    with_[1, :4] = 50.0   # clamp
    grain = rng.normal(0, 0.1, shape + (3,))
    inputs = [("Plate", plate), ("CG", np.concatenate([cg, alpha], -1)), ("With", with_), ("Without", without)]
    files = {}
    for name, img in inputs + ([("Grain", grain)] if form == "grain" else []):
        files[name] = tmp_path / f"{name}.exr"
        write_exr(files[name], img.astype(np.float32))
    settings = {"Ratio Form": 0.0 if form == "additive" else 1.0, "Shadow Clamp": 4.0}
    exposure = 0.0
    if form == "tone":
        exposure = 0.7
        settings.update({"CG Exposure": exposure, "Tone Map": 1.0})
    level, response, amount = np.array([0.5, 1.0, 2.0]), np.array([0.0, 0.5, 1.0]), 0.8
    if form == "grain":
        settings.update({"Grain Amount": amount, "Grain Level": (*level, 1.0), "Grain Response": (*response, 1.0)})
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
    if form == "grain":  # grain scaled to the CG's level, weighted by its alpha
        straight = cg_rgb / np.maximum(alpha, 1e-6)
        cg_rgb = cg_rgb + amount * alpha * grain * np.sqrt(np.maximum(1 - response + response * straight / level, 0))
    expected = cg_rgb + (1 - alpha) * local
    np.testing.assert_allclose(out, expected, rtol=2e-5, atol=2e-5)


def test_cg_blur_softens_edges_and_keeps_energy(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = 64, 32
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    ops_module("common").set_plate_colour_management(scene)
    cg = np.zeros((32, 64, 4), np.float32)
    cg[10:22, 20:44] = (0.8, 0.4, 0.2, 1.0)  # an opaque CG rectangle
    files = {"Plate": tmp_path / "plate.exr", "CG": tmp_path / "cg.exr"}
    write_exr(files["Plate"], np.full((32, 64, 3), 0.5, np.float32))
    write_exr(files["CG"], cg)
    results = {}
    for blur in (0.0, 3.0):
        _group_test_tree(bpy, scene, files, {"CG Blur": blur})
        results[blur] = render(bpy, scene, tmp_path / f"out{blur}.exr")[..., :3]
    sharp, soft = results[0.0], results[3.0]
    np.testing.assert_allclose(sharp[10:22, 20:44], np.broadcast_to((0.8, 0.4, 0.2), (12, 24, 3)), atol=1e-6)
    # blurred: the CG's energy over the plate is kept (to 2 %) and its edge spreads out
    excess = lambda img: (img - 0.5).sum()  # noqa: E731 (the plate is 0.5 everywhere)
    assert abs(excess(soft) - excess(sharp)) < 0.02 * abs(excess(sharp))
    edge_sharp = (np.abs(sharp - 0.5).max(2) > 1e-3).sum()
    edge_soft = (np.abs(soft - 0.5).max(2) > 1e-3).sum()
    assert edge_soft > edge_sharp + 60


def _denoised_sources(tree):
    """(render layer, output) feeding each Denoise node of the compositor tree."""
    return {(node.inputs["Image"].links[0].from_node.name, node.inputs["Image"].links[0].from_socket.name)
            for node in tree.nodes if node.bl_idname == "CompositorNodeDenoise"}


@pytest.mark.parametrize("method", ["CATCHER", "DIFFERENTIAL"])
def test_shadow_passes_are_denoised_by_default(bpy_clean, tmp_path, method):
    """The README's steps take every default: the shadow (or local-scene) passes go through
    OpenImageDenoise unless the artist turns it off (a merge once turned it off), and so does a
    path-traced CG or a sharp reflection; an SBRDF CG of blurred look-ups is not (it only lost its edges)."""
    bpy = bpy_clean
    names = importlib.import_module(f"{support.EXT_MODULE}.addon.names")
    sm = importlib.import_module(f"{support.EXT_MODULE}.node_groups.sbrdf_material")
    scene, _plate = build_scene(bpy, tmp_path, method)          # setup_composite's defaults
    passes = {"CATCHER": {(names.LAYER_CG, "Shadow Catcher")},
              "DIFFERENTIAL": {(names.LAYER_LOCAL, "Image"), (names.LAYER_WITHOUT, "Image")}}[method]
    cg_image = (names.LAYER_CG, "Image")
    assert _denoised_sources(compat().compositor_tree(scene)) == passes | {cg_image}
    if method == "CATCHER":          # guided as Cycles' own denoiser guides a catcher pass
        denoise = next(n for n in compat().compositor_tree(scene).nodes if n.bl_idname == "CompositorNodeDenoise"
                       and n.inputs["Image"].links[0].from_socket.name == "Shadow Catcher")
        assert denoise.inputs["Normal"].links[0].from_socket.name == "Denoising Normal"
        assert denoise.inputs["Albedo"].is_linked
        assert scene.view_layers[names.LAYER_CG].cycles.denoising_store_passes
    sphere = scene.objects["Sphere"]
    sm.apply_sbrdf_material(sphere)                # glossiness 0.5: blurred look-ups only
    assert bpy.ops.platelight.setup_composite(method=method) == {"FINISHED"}
    assert _denoised_sources(compat().compositor_tree(scene)) == passes
    sm.apply_sbrdf_material(sphere, "chrome")      # a sharp reflection: its detail aliases
    assert bpy.ops.platelight.setup_composite(method=method) == {"FINISHED"}
    assert _denoised_sources(compat().compositor_tree(scene)) == passes | {cg_image}
    sm.apply_sbrdf_material(sphere)
    sphere.data.materials.append(compat().new_material("Plain"))      # a second, path-traced slot
    assert bpy.ops.platelight.setup_composite(method=method) == {"FINISHED"}
    assert _denoised_sources(compat().compositor_tree(scene)) == passes | {cg_image}
    assert bpy.ops.platelight.setup_composite(method=method, denoise_shadows=False) == {"FINISHED"}
    assert not any(node.bl_idname == "CompositorNodeDenoise" for node in compat().compositor_tree(scene).nodes)


def test_denoised_cg_keeps_its_edge_pixels_raw(bpy_clean, tmp_path):
    """OIDN knows no alpha: on the CG's edge it mixed in the transparent black around it (a dark
    rim). A path-traced CG is denoised where it covers the pixel; its edge pixels stay as rendered."""
    bpy = bpy_clean
    names = importlib.import_module(f"{support.EXT_MODULE}.addon.names")
    compositor_tree = importlib.import_module(f"{support.EXT_MODULE}.node_groups.compositor_tree")
    scene, _plate = build_scene(bpy, tmp_path, "CATCHER", samples=4)
    tree = compat().compositor_tree(scene)
    raw = compositor_tree.float_exr_file_output(tree, "Raw CG", str(tmp_path / "raw") + "/", ("Raw",), (400, -600))
    tree.links.new(tree.nodes[names.LAYER_CG].outputs["Image"], raw.inputs["Raw"])
    _out, passes = render_with_passes(bpy, scene, tmp_path)
    rendered = read_exr(compositor_tree.pass_output_path(scene, str(tmp_path / "raw"), "Raw"), "RGBA")
    alpha = rendered[..., 3]
    edge, inside = (alpha > 0) & (alpha < 1), alpha == 1
    assert edge.sum() > 20 and inside.sum() > 200
    np.testing.assert_allclose(passes["CG"][..., :3][edge], rendered[..., :3][edge], atol=1e-6)
    assert np.abs(passes["CG"][..., :3][inside] - rendered[..., :3][inside]).max() > 1e-3   # denoised


def test_metals_are_path_traced_in_cycles_unless_asked_for_the_sbrdf(bpy_clean, tmp_path):
    """setup_composite's default shows Cycles' camera an SBRDF metal's Principled twin, path-traced
    (more accurate at equal time, docs/decisions.md): unbaked, the sphere renders as its source
    material did, where the SBRDF without maps renders black. ``metals='SBRDF'`` gives back the
    paper's shading; a dielectric SBRDF keeps it; EEVEE always shows the SBRDF."""
    bpy = bpy_clean
    sm = importlib.import_module(f"{support.EXT_MODULE}.node_groups.sbrdf_material")
    ray_twin = importlib.import_module(f"{support.EXT_MODULE}.node_groups.ray_twin")
    scene, _plate = build_scene(bpy, tmp_path, "CATCHER", samples=16)
    sphere = scene.objects["Sphere"]
    sphere.data.materials.append(metal_material("Copper", (0.8, 0.5, 0.3), 0.3))
    ground, origin, rays = ground_points(bpy, scene)
    inside = inner(sphere_hit(origin, rays))

    def cg():
        assert bpy.ops.platelight.setup_composite(method="CATCHER", samples=16) == {"FINISHED"}
        folder = tmp_path / f"render_{len(list(tmp_path.glob('render_*')))}"
        folder.mkdir()
        _out, passes = render_with_passes(bpy, scene, folder)
        return passes["CG"][..., :3][inside].mean(axis=-1)

    principled = cg()
    assert principled.mean() > 0.05
    material = sm.apply_sbrdf_material(sphere)          # no probe baked: its SBRDF would be black
    assert sm.is_metal(material)
    twin = cg()
    assert not ray_twin.camera_sees_sbrdf(material)
    assert not sm.shaded_by_sbrdf(sphere)               # so its CG is denoised, as a path-traced one
    # the same Principled values path-traced with the same seed: measured equal (difference 0.0)
    assert np.abs(twin - principled).mean() < 0.01 * principled.mean()
    assert bpy.ops.platelight.setup_composite(method="CATCHER", samples=16, metals="SBRDF") == {"FINISHED"}
    assert ray_twin.camera_sees_sbrdf(material)
    folder = tmp_path / "sbrdf"
    folder.mkdir()
    _out, passes = render_with_passes(bpy, scene, folder)
    assert passes["CG"][..., :3][inside].mean() < 0.1 * principled.mean()     # the unbaked SBRDF
    # EEVEE shows the SBRDF (where this machine has no GL context it says so and takes Cycles)
    assert bpy.ops.platelight.setup_composite(method="CATCHER", engine="EEVEE") == {"FINISHED"}
    assert ray_twin.camera_sees_sbrdf(material) == (scene.render.engine != "CYCLES")
    # a dielectric keeps the SBRDF under the default
    sphere.material_slots[0].material = principled_material("Plastic", 0.3)
    dielectric = sm.apply_sbrdf_material(sphere)
    assert not sm.is_metal(dielectric)
    assert bpy.ops.platelight.setup_composite(method="CATCHER", samples=16) == {"FINISHED"}
    assert ray_twin.camera_sees_sbrdf(dielectric) and sm.shaded_by_sbrdf(sphere)


def test_an_sbrdf_object_that_shadows_itself_is_path_traced(bpy_clean, tmp_path):
    """The SBRDF shades from one probe and does not shadow itself: the camera gets the path-traced
    twin in Cycles by default of an object that deforms or whose surface hides part of its own sky
    (docs/decisions.md, "A CG that shadows itself path-traced"); a convex one, still or moving,
    keeps the SBRDF; ``self_shadowing='SBRDF'`` and EEVEE keep the paper's shading."""
    bpy = bpy_clean
    sm = importlib.import_module(f"{support.EXT_MODULE}.node_groups.sbrdf_material")
    ray_twin = importlib.import_module(f"{support.EXT_MODULE}.node_groups.ray_twin")
    scene, _plate = build_scene(bpy, tmp_path, "CATCHER", samples=16)
    scene.frame_start, scene.frame_end = 1, 8
    bulging = scene.objects["Sphere"]
    rolling = add_sphere(bpy, scene, location=(SPHERE_C[0] + 1.0, SPHERE_C[1], SPHERE_C[2]), name="Rolling")
    bpy.ops.mesh.primitive_monkey_add(size=0.6, location=(SPHERE_C[0] - 1.2, SPHERE_C[1], SPHERE_C[2]))
    monkey = bpy.context.object
    monkey.name = "Monkey"
    monkey.platelight.enabled = True
    for ob, name in ((bulging, "Bulging Plastic"), (rolling, "Rolling Plastic"), (monkey, "Monkey Plastic")):
        ob.data.materials.append(principled_material(name, 0.4, (0.6, 0.6, 0.6)))
    bulging.shape_key_add(name="Basis")
    key = bulging.shape_key_add(name="Bulge")
    key.data[0].co = (0.0, 0.0, 2.0 * SPHERE_R)
    rolling.location.x -= 0.5
    rolling.keyframe_insert("location", frame=1)
    rolling.location.x += 0.5
    rolling.keyframe_insert("location", frame=8)
    for frame, value in ((1, 0.0), (8, 1.0)):
        key.value = value
        key.keyframe_insert("value", frame=frame)
    deformed, moved, hollow = (sm.apply_sbrdf_material(ob) for ob in (bulging, rolling, monkey))
    assert not any(sm.is_metal(material) for material in (deformed, moved, hollow))

    assert bpy.ops.platelight.setup_composite(method="CATCHER", samples=16) == {"FINISHED"}
    assert not ray_twin.camera_sees_sbrdf(deformed) and not ray_twin.camera_sees_sbrdf(hollow)
    assert ray_twin.camera_sees_sbrdf(moved)
    assert not sm.shaded_by_sbrdf(bulging) and sm.shaded_by_sbrdf(rolling)   # so it is denoised
    assert bpy.ops.platelight.setup_composite(method="CATCHER", samples=16, self_shadowing="SBRDF") == {"FINISHED"}
    assert ray_twin.camera_sees_sbrdf(deformed) and ray_twin.camera_sees_sbrdf(hollow)
    composite = importlib.import_module(f"{support.EXT_MODULE}.operators.composite")
    lines = composite.setup_composite(scene, method="CATCHER")      # the function the operator calls
    assert not ray_twin.camera_sees_sbrdf(deformed)
    said = " ".join(sentence for _level, sentence in lines)
    assert "path-traced where they shadow themselves (the SBRDF does not): 'Monkey' (hides " in said, said
    assert "'Sphere' (deforms)" in said and "Rolling" not in said.split("shadow themselves")[1]
    assert ray_twin.camera_sees_sbrdf(deformed) == (scene.render.engine != "CYCLES")
