"""Baked shadows (issue 11): the shot's shadow ratio rendered once and looked up every frame.

The reference is analytic: under a uniform sky, a black ball of radius r whose centre is h above
an infinite floor takes away the form factor of a sphere from each floor point, r² cos β / D²
(D the distance to the centre, β the angle from the floor's normal), so the floor's light falls
to 1 − r² h / D³ of what it was. Nothing else is in the scene to bounce light."""
from __future__ import annotations

import importlib

import numpy as np
import pytest

import composite_scene as cs
from bake_scenes import probe_renders
from platelight.addon.exr_io import read_exr
import support
from support import compat

R, HEIGHT = 0.5, 1.0        # the ball floats: its bottom 0.5 m above the floor
CENTRE = np.array([0.0, 0.0, HEIGHT])


def floating_black_ball(bpy, tmp_path, save=True):
    scene = bpy.context.scene
    cs.random_plate(tmp_path / "plate.exr")
    cs.add_camera(bpy, scene)
    floor = cs.add_plane(bpy, scene)
    floor.platelight.phantom = True
    ball = cs.add_sphere(bpy, scene, location=CENTRE, radius=R)
    black = compat().new_material("Black")
    black.node_tree.nodes.clear()
    diffuse = black.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    out = black.node_tree.nodes.new("ShaderNodeOutputMaterial")
    black.node_tree.links.new(diffuse.outputs[0], out.inputs["Surface"])
    ball.data.materials.append(black)
    cs.grey_world(bpy, scene, 1.0)
    scene.platelight.maps_dir = str(tmp_path / "maps")
    if save:
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return scene, floor, ball


def analytic_ratio(ground, centre=CENTRE):
    offset = centre - ground
    distance = np.linalg.norm(offset, axis=-1)
    return 1.0 - R ** 2 * offset[..., 2] / distance ** 3


def test_baked_ratio_matches_the_analytic_shadow_of_a_floating_ball(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    scene, _floor, ball = floating_black_ball(bpy, tmp_path)
    # the camera's exposure scales what reaches it, but a ratio stays a ratio
    scene.cycles.film_exposure = 0.5
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=128, samples=32) == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite(method="BAKED", cg_samples=4) == {"FINISHED"}
    assert "do not match" not in capfd.readouterr().out
    # the baked ratio is noise-free: its layer's samples only anti-alias edges (checked below)
    composite = importlib.import_module(f"{support.EXT_MODULE}.operators.composite")
    layers = {layer.name: layer.samples for layer in scene.view_layers if layer.use}
    assert sorted(layers.values()) == sorted([composite.BAKED_SHADOW_SAMPLES, 4]), layers
    # nothing changed: a second bake renders nothing
    renders = probe_renders()
    assert bpy.ops.platelight.bake_shadows(height=128, samples=32) == {"FINISHED"}
    assert probe_renders() == renders and "up to date" in capfd.readouterr().out
    _image, passes = cs.render_with_passes(bpy, scene, tmp_path / "out")
    ground, origin, rays = cs.ground_points(bpy, scene)
    visible = np.isfinite(ground).all(axis=-1) & ~cs.sphere_hit(origin, rays, CENTRE, R, margin=0.05)
    near = visible & (np.linalg.norm(ground[..., :2], axis=-1) < 2.0)
    expected = analytic_ratio(ground)
    ratio = passes["Shadows"][..., :3].mean(axis=-1)
    assert near.sum() > 300
    assert expected[near].min() < 0.8                                # the shadow is in view
    error = np.abs(ratio[near] - expected[near])
    assert np.median(error) < 0.02 and np.percentile(error, 95) < 0.05, (np.median(error), np.percentile(error, 95))
    # only the floor's rows were rendered: the sky's stay "no change" (ratio - 1 = 0) exactly
    texture = read_exr(tmp_path / "maps" / "_shadows" / "shadow_ratio.exr", "RGB")
    assert texture.shape == (128, 256, 3) and not texture[:32].any() and texture[64:].min() < -0.2
    # far away the plate is untouched
    far = visible & (np.linalg.norm(ground[..., :2], axis=-1) > 12.0)
    if far.any():
        assert np.abs(ratio[far] - 1.0).max() < 0.01

    # the default method takes a current bake
    assert bpy.ops.platelight.setup_composite() == {"FINISHED"}
    assert "(baked, cycles)" in capfd.readouterr().out

    # the ball moved: the bake is stale, and the composite says so
    ball.location.z += 0.2
    assert bpy.ops.platelight.setup_composite(method="BAKED", cg_samples=4) == {"FINISHED"}
    assert "run Bake Shadows again" in capfd.readouterr().out
    # and the default method does not take it
    assert bpy.ops.platelight.setup_composite() == {"FINISHED"}
    said = capfd.readouterr().out
    assert "(catcher, cycles)" in said and "Shadow Catcher renders them instead" in said
    # EEVEE has no shadow catcher: the warning names what it renders instead
    assert bpy.ops.platelight.setup_composite(engine="EEVEE") == {"FINISHED"}
    assert "EEVEE renders its own instead" in capfd.readouterr().out
    assert bpy.ops.platelight.setup_composite() == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=128, samples=32) == {"FINISHED"}
    assert probe_renders() > renders


def test_bake_restores_the_scene_and_bad_input_is_one_sentence(bpy_clean, tmp_path):
    from platelight.addon import names
    from platelight.operators.baked_shadows import SHADOW_BAKE_DIFFUSE_BOUNCES

    bpy = bpy_clean
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    # the method before a bake: said, nothing changed
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="run Bake Shadows"):
        bpy.ops.platelight.setup_composite(method="BAKED")

    # a phantom that moves during the shot (the one-frame plate made the shot one frame long)
    scene.frame_end = 10
    floor.keyframe_insert("location", frame=1)
    floor.location.x += 1.0
    floor.keyframe_insert("location", frame=10)
    scene.frame_set(1)
    with pytest.raises(RuntimeError, match="'Ground' moves during the shot .from frame 2.: baked shadows "
                       "need phantoms that stand still"):
        bpy.ops.platelight.bake_shadows(height=32, samples=2)
    floor.animation_data_clear()
    floor.location = (0.0, 0.0, 0.0)
    scene.frame_end = 1

    # no phantoms
    floor.platelight.phantom = False
    with pytest.raises(RuntimeError, match="no phantoms"):
        bpy.ops.platelight.bake_shadows(height=32, samples=2)
    floor.platelight.phantom = True

    def state():
        return (scene.camera.name, scene.render.resolution_x, scene.render.resolution_y,
                scene.cycles.samples, scene.cycles.use_denoising, scene.render.filepath,
                ball.visible_camera, ball.hide_render, floor.is_shadow_catcher, len(bpy.data.objects),
                scene.render.use_border, scene.render.border_min_y, scene.render.border_max_y,
                scene.cycles.diffuse_bounces)

    scene.cycles.diffuse_bounces = 6
    before = state()
    bounces = []                 # what each of the bake's panorama renders traced with

    def seen(scene_, *_):
        if scene_.camera is not None and scene_.camera.name == names.PROBE_CAMERA:
            bounces.append(scene_.cycles.diffuse_bounces)

    bpy.app.handlers.render_pre.append(seen)
    try:
        assert bpy.ops.platelight.bake_shadows(height=32, samples=2) == {"FINISHED"}
    finally:
        bpy.app.handlers.render_pre.remove(seen)
    assert state() == before
    # the bake's bounces capped (deeper ones add noise, not ratio), the scene's kept
    assert len(bounces) == 2 and set(bounces) == {SHADOW_BAKE_DIFFUSE_BOUNCES}, bounces
    assert (tmp_path / "maps" / "_shadows" / "shadow_ratio.exr").is_file()
    # a second run replaces the bake in place: one material, no duplicates
    assert bpy.ops.platelight.bake_shadows(height=32, samples=2) == {"FINISHED"}
    assert len([m for m in bpy.data.materials if m.name.startswith("PlateLight Baked Shadows")]) == 1


def test_cli_bake_bakes_the_shots_shadows_of_a_baked_composite(bpy_clean, tmp_path):
    """A farm's bake step (`python -m platelight bake`) re-bakes the shadows of a .blend composited
    with the BAKED method; a part other than the first leaves them to part 1."""
    import support

    bpy = bpy_clean
    scene, _floor, ball = floating_black_ball(bpy, tmp_path)
    ball.platelight.enabled = False                     # no probes: the shadows alone
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=32, samples=2) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(method="BAKED") == {"FINISHED"}
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    ratio = tmp_path / "maps" / "_shadows" / "shadow_ratio.exr"
    ratio.unlink()
    second = support.run_cli("bake", tmp_path / "scene.blend", "--frames", "1-1", "--part", "2/2")
    assert second.returncode == 0, second.stderr
    assert not ratio.exists()
    result = support.run_cli("bake", tmp_path / "scene.blend")
    assert result.returncode == 0, result.stderr
    assert ratio.is_file() and "Shadows baked" in result.stdout
    # baked from the saved file's view layers: the ball's shadow is in it
    assert read_exr(ratio, "RGB").min() < -0.2
    again = support.run_cli("bake", tmp_path / "scene.blend")
    assert again.returncode == 0, again.stderr
    assert "up to date" in again.stdout


def test_a_shadow_bake_after_a_probe_of_its_size_reads_its_own_render(bpy_clean, tmp_path, studio_hdris):
    """The benchmark's diffuse ball: its probe (64 rows) has a 256-row distance map, and a 256-row
    shadow bake right after it once wrote that map as its first panorama (the single-layer render
    kept the probe's layer in its result): a ratio of 4 over the far floor, no shadow under the
    ball. Its own render: no change far off, the contact shadow under the ball."""
    import importlib.util

    import support

    bpy = bpy_clean
    spec = importlib.util.spec_from_file_location(
        "bench_composite_for_shadows", support.REPO / "tests" / "bench" / "bench_composite.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    bench.W, bench.H = 160, 90
    scene, floor, sphere = bench.build(bpy, str(studio_hdris["city"]), bench.MATERIALS["diffuse"])
    floor.platelight.phantom = True
    bench.sbrdf_sphere(bpy, scene, sphere, tmp_path / "frame")
    assert (tmp_path / "frame_probes" / sphere.name / "distance.exr").is_file()
    assert scene.platelight.probe_height == 64
    assert bpy.ops.platelight.bake_shadows(height=256, samples=4) == {"FINISHED"}
    texture = read_exr(tmp_path / "frame_probes" / "_shadows" / "shadow_ratio.exr", "RGB")
    assert np.abs(texture[136:176]).max() < 0.05           # the floor 2-6 m off (was 3: ratio 4)
    assert texture[250:].mean() < -0.3                      # under the ball (measured -0.5)


def test_the_catcher_bake_agrees_with_two_renders_and_restores_the_scene(bpy_clean, tmp_path):
    """The one-render bake (the phantoms as Cycles shadow catchers, their Shadow Catcher pass)
    against the two renders divided: the same ratio in the shadow (a grey ball, so its bounce
    light counts), exactly "no change" wherever the panorama sees sky, and the scene as it was."""
    from platelight.addon.ibl import distance as distance_maps

    bpy = bpy_clean
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    ball.data.materials[0].node_tree.nodes["Diffuse BSDF"].inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    floor.is_shadow_catcher = True          # the user's flag: the bake leaves it as it was
    folder = tmp_path / "maps" / "_shadows"

    def state():
        fmt = scene.render.image_settings
        return ([(layer.name, layer.use, layer.cycles.use_pass_shadow_catcher) for layer in scene.view_layers],
                getattr(fmt, "media_type", None), fmt.file_format, fmt.color_mode, fmt.color_depth,
                scene.render.film_transparent,
                scene.render.filepath, scene.camera.name, scene.cycles.samples, scene.cycles.use_denoising,
                floor.is_shadow_catcher, [slot.material.name for slot in floor.material_slots if slot.material],
                ball.visible_camera, ball.hide_render, len(bpy.data.objects),
                [im.name for im in bpy.data.images if im.type == "RENDER_RESULT"],
                scene.render.use_border, scene.render.border_min_y, scene.render.border_max_y)

    def bake(method):
        renders = probe_renders()
        assert bpy.ops.platelight.bake_shadows(height=64, samples=16, method=method) == {"FINISHED"}
        assert probe_renders() - renders == {"CATCHER": 1, "TWO_RENDERS": 2}[method]
        texture = read_exr(folder / "shadow_ratio.exr", "RGB")
        depth = read_exr(folder / distance_maps.distance_filename(), "RGB")[..., 0]
        # a ratio texel sees sky where every distance texel over it does (the map is 4x finer)
        sky = (depth.reshape(64, 4, 128, 4) >= distance_maps.FAR).all(axis=(1, 3))
        return texture, sky

    before = state()
    two, sky = bake("TWO_RENDERS")
    assert state() == before
    # another method is another bake: renders again, and the record says which
    caught, sky_caught = bake("CATCHER")
    assert state() == before
    assert (sky_caught == sky).all() and sky.sum() > 1000
    assert '"method": "CATCHER"' in (folder / "shadow_ratio.json").read_text()
    # ratio 1 over the sky: exactly from the catcher (the Combined alpha tells the sky); the two
    # renders divide two denoised path-traced skies (this world is no image laid under)
    assert not caught[sky].any() and np.abs(two[sky]).max() < 0.05      # measured 0.016
    shadow = two.mean(axis=-1) < -0.03
    assert shadow.sum() > 100 and two.min() < -0.1                      # measured -0.157
    difference = np.abs(caught - two).mean(axis=-1)
    # measured 0.0043 (95th percentile 0.011) in the shadow, 0.0018 over the panorama: the two
    # denoisers' residual noise (undenoised the two are equal)
    assert difference[shadow].mean() < 0.01, difference[shadow].mean()
    assert np.abs(caught - two).mean() < 0.005, np.abs(caught - two).mean()
    # the same method again: nothing to render
    renders = probe_renders()
    assert bpy.ops.platelight.bake_shadows(height=64, samples=16, method="CATCHER") == {"FINISHED"}
    assert probe_renders() == renders


def test_the_compositor_denoised_catcher_agrees_with_cycles_and_leaves_the_compositor(bpy_clean, tmp_path):
    """The catcher render undenoised, its Shadow Catcher pass alone denoised by the compositor's
    Denoise node in a temporary scene: the ratio Cycles' denoiser gives within the two denoisers'
    residual noise, the sky exactly "no change", the user's compositor as it was (on 4.5 the
    scene's own tree) and nothing of the temporary scene left behind."""
    from platelight.addon import names
    from platelight.addon.ibl import distance as distance_maps

    bpy = bpy_clean
    compat_ = compat()
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    ball.data.materials[0].node_tree.nodes["Diffuse BSDF"].inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    tree = compat_.new_compositor_tree(scene, "User Composite")
    tree.nodes.new("CompositorNodeBlur").name = "User Blur"
    folder = tmp_path / "maps" / "_shadows"

    def compositor():
        tree = compat_.compositor_tree(scene)
        return (tree.name, sorted(n.name for n in tree.nodes), getattr(scene, "use_nodes", None),
                scene.render.use_compositing)

    def data():
        return ([s.name for s in bpy.data.scenes], sorted(i.name for i in bpy.data.images),
                sorted(g.name for g in bpy.data.node_groups))

    def bake(denoiser):
        renders = probe_renders()
        assert bpy.ops.platelight.bake_shadows(height=64, samples=16, method="CATCHER",
                                               denoiser=denoiser) == {"FINISHED"}
        assert probe_renders() - renders == 1          # the compositor's render is no Cycles render
        assert f'"denoiser": "{denoiser}"' in (folder / "shadow_ratio.json").read_text()
        return read_exr(folder / "shadow_ratio.exr", "RGB")

    before = compositor()
    by_cycles = bake("CYCLES")
    after_cycles = data()
    by_compositor = bake("COMPOSITOR")
    assert compositor() == before
    assert data() == after_cycles
    assert not any(names.PASS_DENOISE in name for group in data() for name in group)
    depth = read_exr(folder / distance_maps.distance_filename(), "RGB")[..., 0]
    sky = (depth.reshape(64, 4, 128, 4) >= distance_maps.FAR).all(axis=(1, 3))
    assert sky.sum() > 1000
    assert not by_compositor[sky].any()        # the Combined alpha tells the sky: exactly 1
    shadow = by_cycles.mean(axis=-1) < -0.03
    assert shadow.sum() > 100
    difference = np.abs(by_compositor - by_cycles).mean(axis=-1)
    # measured 0.00012 (95th percentile 0.00024, max 0.0027-0.0029) in the shadow, 0.000025 over
    # the panorama on 4.5, 5.2 and 5.3: OIDN on the same pass with the same guides. Without the
    # guides as Cycles gives them 0.0055 / 0.0012; with the normal read as grey 0.0031 / 0.0008
    assert difference[shadow].mean() < 0.001, difference[shadow].mean()
    assert difference.mean() < 0.0002, difference.mean()
    # the same denoiser again: nothing to render
    renders = probe_renders()
    assert bpy.ops.platelight.bake_shadows(height=64, samples=16, method="CATCHER",
                                           denoiser="COMPOSITOR") == {"FINISHED"}
    assert probe_renders() == renders


def test_a_catcher_bake_below_four_samples_warns(bpy_clean, tmp_path):
    """At 1 sample the catcher's denoised shadow is 9.5 dB below the two renders' (bench): the
    bake still runs, and says so in one sentence; the two renders' bake does not."""
    from bl_ext.dev.platelight.operators import baked_shadows

    bpy = bpy_clean
    floating_black_ball(bpy, tmp_path)
    summary = baked_shadows.bake_shadows(bpy.context, height=16, samples=1, method="CATCHER")
    assert [w for w in summary["warnings"] if "grainy" in w] == [
        "At 1 sample(s) the Shadow Catcher bake's shadow is grainy; bake with 4 or more samples, "
        "or with the Two Renders method."]
    summary = baked_shadows.bake_shadows(bpy.context, height=16, samples=1, method="TWO_RENDERS")
    assert not [w for w in summary["warnings"] if "grainy" in w]


def test_a_shadow_bake_renders_with_the_cg_s_probe_maps_set_aside(bpy_clean, tmp_path):
    """No camera ray of a shadow bake sees the CG, so its SBRDF's maps (image sequences after a
    frame-range probe bake, which Cycles reloaded at every frame) are held at the black stand-in
    while it renders, and bound again after."""
    from platelight.addon.names import UNBAKED_MAP
    from platelight.node_groups.probe_maps import map_nodes

    bpy = bpy_clean
    sm = importlib.import_module(f"{support.EXT_MODULE}.node_groups.sbrdf_material")
    scene, _floor, ball = floating_black_ball(bpy, tmp_path)
    ball.platelight.enabled = True
    scene.platelight.probe_height = 16
    scene.frame_start, scene.frame_end = 1, 3
    for frame, x in ((1, 0.0), (3, 1.0)):
        ball.location.x = x
        ball.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    material = sm.apply_sbrdf_material(ball)
    assert bpy.ops.platelight.bake_probes(all_objects=True, frame_start=1, frame_end=3, cull=False) == {"FINISHED"}
    group = sm.probe_node(material).node_tree
    bound = {node.name: node.image.name for node in map_nodes(group)}
    assert set(bound.values()) != {UNBAKED_MAP}
    seen, filming_camera = [], scene.camera

    def note_images(*_):
        if scene.camera is not filming_camera:       # the bake's panoramas, not the phantoms' white render
            seen.append({node.image.name for node in map_nodes(group)})

    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    bpy.app.handlers.render_pre.append(note_images)
    try:
        assert bpy.ops.platelight.bake_shadows(height=32, samples=2, moving_shadows="PER_FRAME",
                                               moving_height=32) == {"FINISHED"}
    finally:
        bpy.app.handlers.render_pre.remove(note_images)
    assert len(seen) >= 3 and all(images == {UNBAKED_MAP} for images in seen), seen
    assert {node.name: node.image.name for node in map_nodes(group)} == bound


def test_what_the_camera_sees_of_a_metal_leaves_the_bake_current(bpy_clean, tmp_path, capfd):
    """The bake hides the CG from its camera, so setup_composite's Metals switch (the camera sees a
    metal's SBRDF or its path-traced twin) cannot change the ratio: the bake stays current and the
    default method keeps taking it (it fell back to the catcher once the switch was flipped)."""
    bpy = bpy_clean
    sm = importlib.import_module(f"{support.EXT_MODULE}.node_groups.sbrdf_material")
    ray_twin = importlib.import_module(f"{support.EXT_MODULE}.node_groups.ray_twin")
    baked = importlib.import_module(f"{support.EXT_MODULE}.operators.baked_shadows")
    scene, _floor, ball = floating_black_ball(bpy, tmp_path, save=False)
    ball.material_slots[0].material = cs.metal_material("Chrome", (0.9, 0.9, 0.9), 0.0)
    material = sm.apply_sbrdf_material(ball)
    assert sm.is_metal(material) and ray_twin.camera_sees_sbrdf(material)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=64, samples=4) == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite() == {"FINISHED"}       # Cycles: the metal path-traced
    said = capfd.readouterr().out
    assert not ray_twin.camera_sees_sbrdf(material)
    assert "(baked, cycles)" in said and "do not match" not in said, said
    # a path-traced CG converges: its layer's automatic samples, adaptive sampling stopping clean pixels
    assert "the CG at 64 samples" in said and scene.cycles.use_adaptive_sampling
    assert scene.view_layers["PlateLight CG"].samples == 64
    for value in (True, False):
        ray_twin.set_camera_sees_sbrdf(material, value)
        assert baked.baked_is_current(scene)
    # what other rays meet still counts: the twin's colour lights the floor
    compat().node_tree(material).nodes[ray_twin.TWIN_NODE].inputs["Base Color"].default_value = (0.1, 0.9, 0.1, 1.0)
    assert not baked.baked_is_current(scene)
    # a noise-free SBRDF needs only its edges anti-aliased: 4 samples
    ball.material_slots[0].material = cs.principled_material("Plastic", 0.6)
    assert not sm.is_metal(sm.apply_sbrdf_material(ball))
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite(method="BAKED") == {"FINISHED"}
    assert "the CG at 4 samples" in capfd.readouterr().out
    assert scene.view_layers["PlateLight CG"].samples == 4


def test_a_mirror_sees_the_filmed_floor_shadowed_and_without_noise(bpy_clean, tmp_path, capfd):
    """With baked shadows the CG's rays meet the phantoms as the camera filmed them, times the
    baked ratio (node_groups/phantom_plate.py). A chrome ball's reflection of the floor is then
    noise-free at one sample (two seeds give the same pixels) and agrees with the floor
    path-traced at 64 samples (the plate's albedo under the sky, shadowed by the ball itself)."""
    from platelight.addon import names
    from platelight.addon.exr_io import write_exr

    bpy = bpy_clean
    scene, _floor, ball = floating_black_ball(bpy, tmp_path, save=False)
    ball.material_slots[0].material = cs.metal_material("Chrome", (0.9, 0.9, 0.9), 0.0)
    centre = np.array([0.0, 0.0, R + 0.1])          # 10 cm over the floor: a deep shadow under it
    ball.location = tuple(centre)
    j, i = np.mgrid[0:cs.H, 0:cs.W] / np.array([cs.H, cs.W])[:, None, None]
    plate = np.stack([0.35 + 0.2 * np.sin(4 * i), 0.35 + 0.2 * np.cos(3 * j), 0.3 + 0.1 * i * j], -1)
    write_exr(tmp_path / "plate.exr", plate.astype(np.float32))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=128, samples=32) == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite(method="BAKED", cg_samples=1, denoise_shadows=False) == {"FINISHED"}
    cg_layer = scene.view_layers[names.LAYER_CG]
    assert cg_layer[names.FILMED_PHANTOMS_KEY] == 1.0
    # a path that ends on the filmed floor counts as direct light: clamped (Cycles' default: off),
    # and the artist is told
    assert scene.cycles.sample_clamp_direct == 100.0
    assert "direct light clamped at 100 (was off)" in capfd.readouterr().out
    scene.cycles.pixel_filter_type = "BOX"      # pixel centres: the same mirror point at any seed
    scene.cycles.filter_width = 0.01

    def cg(seed, folder):
        scene.cycles.seed = seed
        return cs.render_with_passes(bpy, scene, tmp_path / folder)[1]["CG"][..., :3]

    one, other = cg(1, "a"), cg(2, "b")
    cg_layer[names.FILMED_PHANTOMS_KEY] = 0.0
    traced_one, traced_other = cg(1, "c"), cg(2, "d")
    cg_layer.samples = 64
    traced = cg(1, "e")
    # the ball's pixels whose mirror ray meets the floor in the plate's frame, in the ball's shadow
    ground, origin, rays = cs.ground_points(bpy, scene)
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    oc = origin - centre
    b = d @ oc
    disc = b * b - (oc @ oc - R ** 2)
    hit = origin + (-b - np.sqrt(np.maximum(disc, 0)))[..., None] * d
    normal = (hit - centre) / R
    reflected = d - 2 * (d * normal).sum(-1, keepdims=True) * normal
    down = cs.inner(disc > 0, 2) & (reflected[..., 2] < -0.2)
    floor_hit = hit - hit[..., 2:3] / np.where(down[..., None], reflected[..., 2:3], -1.0) * reflected
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    uv = np.array([world_to_camera_view(scene, scene.camera, Vector(tuple(map(float, p))))[:2]
                   for p in floor_hit.reshape(-1, 3)]).reshape(cs.H, cs.W, 2)
    framed = (uv > 0.02).all(-1) & (uv < 0.98).all(-1)
    shadow = analytic_ratio(floor_hit, centre)
    shadowed = down & framed & (shadow < 0.9)
    assert shadowed.sum() >= 10, shadowed.sum()
    # noise-free where path tracing the floor is not
    assert np.abs(one - other)[shadowed].max() < 1e-4
    noise = np.abs(traced_one - traced_other)[shadowed].mean()
    # what the camera filmed there (the plate), times the analytic shadow, times the chrome's
    # reflectance (0.9 head-on, more towards grazing)
    col = np.clip((uv[..., 0] * cs.W).astype(int), 0, cs.W - 1)
    row = np.clip(((1 - uv[..., 1]) * cs.H).astype(int), 0, cs.H - 1)
    expected = plate[row, col] * shadow[..., None]
    reflectance = (one / expected)[shadowed].mean(-1)
    agreement = one[shadowed].mean(-1) / traced[shadowed].mean(-1)
    # measured: path-traced at one sample 0.086 apart between seeds; reflectance 0.95 / 0.97 /
    # 1.03 (5th, 50th, 95th percentile: the chrome ball lights its own shadow a little, which
    # the analytic black ball does not); against the floor path-traced 0.97 / 0.99 / 1.06
    assert noise > 0.03, noise
    assert 0.9 < np.median(reflectance) < 1.05 and np.percentile(reflectance, 5) > 0.85
    assert abs(np.median(agreement) - 1) < 0.03 and np.percentile(np.abs(agreement - 1), 90) < 0.1

    # a CG that moves far off makes the floor a shadow catcher (its shadow every frame): the
    # mirror still sees the floor as filmed, shadowed as before
    far = cs.add_sphere(bpy, scene, location=(30.0, 30.0, 1.0), radius=R, name="Far")
    scene.frame_start, scene.frame_end = 1, 8
    for frame, x in ((1, 30.0), (8, 32.0)):
        far.location.x = x
        far.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    cg_layer[names.FILMED_PHANTOMS_KEY] = 1.0
    assert bpy.ops.platelight.bake_shadows(height=128, samples=32, moving_shadows="CATCHER") == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(cg_samples=1, denoise_shadows=False) == {"FINISHED"}
    assert "(mixed, cycles)" in capfd.readouterr().out and _floor.is_shadow_catcher
    mixed = cg(1, "f")
    assert np.percentile(np.abs(mixed[shadowed] / one[shadowed] - 1), 90) < 0.02


def test_the_bake_bounces_the_cg_s_light_off_the_phantoms_at_their_filmed_albedo(bpy_clean, tmp_path):
    """A white ball over a floor filmed dark, then bright: the bake renders the floor at the
    albedo the plate gives it, so under the ball (where the ball's underside, lit by the floor,
    sends light back) the brighter floor's ratio is higher; a fixed grey would bake both alike."""
    from platelight.addon import names
    from platelight.addon.exr_io import write_exr

    bpy = bpy_clean
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    ball.data.materials[0].node_tree.nodes["Diffuse BSDF"].inputs["Color"].default_value = (0.8, 0.8, 0.8, 1)
    shadows = importlib.import_module(f"{support.EXT_MODULE}.operators.baked_shadows")
    under = {}
    for grey, name in ((0.2, "dark"), (0.8, "bright")):
        plate = tmp_path / f"{name}.exr"
        write_exr(plate, np.full((cs.H, cs.W, 3), grey, np.float32))
        assert bpy.ops.platelight.setup_plate(filepath=str(plate)) == {"FINISHED"}
        assert bpy.ops.platelight.bake_shadows(height=64, samples=16, force=True) == {"FINISHED"}
        # a white floor under the uniform sky of 1 films 1: the plate's value is the albedo
        assert shadows.matte_albedo(floor) == pytest.approx((grey,) * 3, abs=0.03)
        assert list(floor[names.MEAN_ALBEDO_KEY]) == pytest.approx([grey] * 3, abs=0.03)
        ratio = read_exr(tmp_path / "maps" / names.SHADOWS_FOLDER / "shadow_ratio.exr") + 1.0
        under[grey] = float(ratio[-4:].mean())           # straight down: the floor under the ball
    black = analytic_ratio(np.zeros(3))                   # 0.75: what a black ball leaves
    assert under[0.2] > black + 0.01 and under[0.8] > under[0.2] + 0.03, under
