"""Plate and composite set-up: bad input gets one clear sentence and leaves the scene as it was;
8-bit plates round-trip exactly; sequences keep their frame numbers; re-running never duplicates."""
import importlib
import math

import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.exr_io import read_exr, write_exr
from composite_scene import add_camera, add_plane, add_sphere, add_sun, grey_world, random_plate, render
from support import compat


def png(path, rgb8):
    import cv2

    assert cv2.imwrite(str(path), np.ascontiguousarray(rgb8[..., ::-1]))


def scene_state(bpy):
    scene = bpy.context.scene
    return {
        "resolution": (scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage),
        "frames": (scene.frame_start, scene.frame_end),
        "fps": (scene.render.fps, scene.render.fps_base),
        "view_layers": [(vl.name, vl.use) for vl in scene.view_layers],
        "collections": sorted(c.name for c in bpy.data.collections),
        "objects": sorted((ob.name, tuple(sorted(c.name for c in ob.users_collection)), ob.is_shadow_catcher)
                          for ob in scene.objects),
        # Blender's own render and viewer images (4.5 keeps a "Viewer Node") are not the scene's
        "images": sorted(i.name for i in bpy.data.images if i.type not in {"RENDER_RESULT", "COMPOSITING"}),
        "node_groups": sorted(g.name for g in bpy.data.node_groups),
        "tree": compat().compositor_tree(scene).name if compat().compositor_tree(scene) else None,
        "view": scene.view_settings.view_transform,
        "engine": scene.render.engine,
    }


def basic_scene(bpy, tmp_path, phantoms=True):
    scene = bpy.context.scene
    add_camera(bpy, scene)
    if phantoms:
        add_plane(bpy, scene).platelight.phantom = True
    add_sphere(bpy, scene)
    add_sun(bpy, scene)
    grey_world(bpy, scene, 0.0)
    return scene


def test_composite_without_plate_is_refused_and_scene_kept(bpy_clean):
    bpy = bpy_clean
    basic_scene(bpy, None)
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match="No plate found"):
        bpy.ops.platelight.setup_composite()
    assert scene_state(bpy) == before


def test_composite_without_cg_is_refused(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    add_plane(bpy, scene).platelight.phantom = True
    random_plate(tmp_path / "plate.exr")
    bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr"))
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match="no CG objects"):
        bpy.ops.platelight.setup_composite()
    assert scene_state(bpy) == before


def test_composite_needs_a_camera(bpy_clean):
    bpy = bpy_clean
    add_sphere(bpy, bpy.context.scene)
    with pytest.raises(RuntimeError, match="needs a camera"):
        bpy.ops.platelight.setup_composite()


def _ext(module):
    return importlib.import_module(f"{support.EXT_MODULE}.{module}")


def test_setup_composite_as_a_function(bpy_clean, tmp_path):
    """setup_composite(scene), the operator's work as a function: a refusal is a PlateLightError
    with the operator's sentence and leaves the scene as it was; a run returns the report's lines
    and uses the route's view layers."""
    bpy = bpy_clean
    composite, errors = _ext("operators.composite"), _ext("addon.errors")
    scene = basic_scene(bpy, tmp_path)
    before = scene_state(bpy)
    with pytest.raises(errors.PlateLightError, match="No plate found"):
        composite.setup_composite(scene)
    assert scene_state(bpy) == before
    random_plate(tmp_path / "plate.exr")
    bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr"))
    before = scene_state(bpy)
    with pytest.raises(errors.PlateLightError, match="needs the shot's shadows"):
        composite.setup_composite(scene, method="BAKED")
    assert scene_state(bpy) == before
    lines = composite.setup_composite(scene, method="LAYERED", samples=4)
    assert [level for level, _ in lines] == ["INFO"], lines
    assert lines[0][1].startswith("Composite set up (layered, cycles): 1 CG object(s)"), lines
    assert {layer.name for layer in scene.view_layers if layer.use} == composite.ROUTES["LAYERED"].layers


def test_choose_route_asks_for_the_scene_only_where_a_bake_could_serve(bpy_module):
    routes, errors = _ext("operators.composite.routes"), _ext("addon.errors")

    def never(*_moving):
        raise AssertionError("asked without a bake to use")

    choice = routes.choose_route("AUTO", "CYCLES", baked=False, motion_blur=False, motions=never,
                                 is_current=never)
    assert (choice.route.name, choice.engine, choice.reports, choice.current) == ("CATCHER", "CYCLES", (), None)
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=False, motions=dict,
                                 is_current=lambda moving: moving == frozenset())
    assert (choice.route.name, choice.reports, choice.current, choice.moving) == ("BAKED", (), True, frozenset())
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=False, motions=dict,
                                 is_current=lambda moving: False)
    assert choice.route.name == "CATCHER" and choice.current is False
    assert choice.reports == (("WARNING", "The baked shadows do not match the scene any more: the Shadow "
                               "Catcher renders them instead; run Bake Shadows again to use them."),)
    choice = routes.choose_route("BAKED", "CYCLES", baked=True, motion_blur=False, motions=dict,
                                 is_current=never)        # hashed after the build
    assert (choice.route.name, choice.current) == ("BAKED", None)
    with pytest.raises(errors.PlateLightError, match="Motion Blur off"):
        routes.choose_route("CATCHER", "EEVEE", baked=False, motion_blur=True, motions=never, is_current=never)

    # a moving CG: a bake that left it out serves the rest (MIXED), by name too; one that holds it does not
    rolling = {"Ball": _ext("operators.motion").Motion("Ball", "moves", 2)}
    for method in ("AUTO", "BAKED"):
        choice = routes.choose_route(method, "CYCLES", baked=True, motion_blur=False, motions=lambda: rolling,
                                     is_current=lambda moving: moving == {"Ball"}, phantom_names={"Floor"})
        assert (choice.route.name, choice.reports, choice.moving) == ("MIXED", (), frozenset({"Ball"}))
    # ... or where the bake holds its shadows at every frame, the baked layer alone
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=False, motions=lambda: rolling,
                                 is_current=lambda moving: moving == {"Ball"}, phantom_names={"Floor"},
                                 moving_baked=lambda: True)
    assert (choice.route.name, choice.reports, choice.moving) == ("BAKED", (), frozenset())
    # ... but not under Motion Blur: a panorama per frame does not blur with the CG
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=True, motions=lambda: rolling,
                                 is_current=lambda moving: True, phantom_names={"Floor"},
                                 moving_baked=lambda: True)
    assert choice.route.name == "CATCHER" and "Motion Blur is on" in choice.reports[0][1]
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=False, motions=lambda: rolling,
                                 is_current=lambda moving: False, phantom_names={"Floor"})
    assert choice.route.name == "CATCHER" and choice.moving == frozenset()
    assert "'Ball' moves during the shot (from frame 2): the Shadow Catcher renders" in choice.reports[0][1]
    with pytest.raises(errors.PlateLightError, match="baked with it cannot follow it: bake the shadows again"):
        routes.choose_route("BAKED", "CYCLES", baked=True, motion_blur=False, motions=lambda: rolling,
                            is_current=lambda moving: False, phantom_names={"Floor"})
    # a moving phantom leaves no bake usable: not even asked
    choice = routes.choose_route("AUTO", "CYCLES", baked=True, motion_blur=False, motions=lambda: rolling,
                                 is_current=never, phantom_names={"Ball"})
    assert (choice.route.name, choice.current) == ("CATCHER", None)


def test_no_phantoms_still_composites_and_says_so(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    scene = basic_scene(bpy, tmp_path, phantoms=False)
    plate = random_plate(tmp_path / "plate.exr")
    bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr"))
    assert bpy.ops.platelight.setup_composite(samples=4) == {"FINISHED"}
    assert "no phantoms" in capfd.readouterr().out
    out = render(bpy, scene, tmp_path / "out.exr")
    alpha_free = np.all(np.abs(out[..., :3] - plate) <= 1e-6, axis=2)
    assert 0.6 < alpha_free.mean() < 0.99  # the plate everywhere but on the sphere: no shadow


def test_rerunning_never_duplicates(bpy_clean, tmp_path):
    bpy = bpy_clean
    basic_scene(bpy, tmp_path)
    random_plate(tmp_path / "plate.exr")
    for method in ("DIFFERENTIAL", "CATCHER", "DIFFERENTIAL"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr"))
        assert bpy.ops.platelight.setup_composite(method=method) == {"FINISHED"}
    state = scene_state(bpy)
    assert state["images"] == ["PlateLight Phantom Albedo", "PlateLight Phantom Radiance", "PlateLight Plate"]   # one of each
    tree = compat().compositor_tree(bpy.context.scene)
    own_tree = [tree.name] if tree.name in bpy.data.node_groups else []   # 4.5: the scene's own tree
    # the phantoms' plate material holds the baked ratio group (ratio 1 before any bake)
    assert state["node_groups"] == sorted(["PlateLight Baked Ratio", "PlateLight Differential"] + own_tree)
    assert [c for c in state["collections"] if c.startswith("PlateLight")] == ["PlateLight CG", "PlateLight Phantoms"]
    assert [n for n, use in state["view_layers"] if use] == [
        "PlateLight CG", "PlateLight Local", "PlateLight Local Without"]


def test_missing_file_and_unreadable_file(bpy_clean, tmp_path):
    bpy = bpy_clean
    add_camera(bpy, bpy.context.scene)
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match="Plate file not found"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "nope.png"))
    (tmp_path / "fake.png").write_text("not an image")
    with pytest.raises(RuntimeError, match="cannot read"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "fake.png"))
    assert scene_state(bpy) == before


def test_missing_frames_in_sequence(bpy_clean, tmp_path):
    bpy = bpy_clean
    add_camera(bpy, bpy.context.scene)
    for n in (1, 2, 4, 5):
        png(tmp_path / f"plate_{n:04d}.png", np.full((18, 32, 3), 40 * n, np.uint8))
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match=r"1 missing frame\(s\) \(3\)"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate_0001.png"))
    assert scene_state(bpy) == before


def test_size_and_rate_mismatch_refused_unless_adopted(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    for n in (1, 2, 3):
        png(tmp_path / f"p{n}.png", np.full((18, 32, 3), 50 * n, np.uint8))
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match=r"plate is 32×18 but the scene renders 1920×1080.*adopt"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "p1.png"), match_scene=False)
    with pytest.raises(RuntimeError, match="runs at 30 fps but the scene at 24 fps"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "p1.png"), match_scene=False, fps=30)
    assert scene_state(bpy) == before
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "p1.png"), fps=30) == {"FINISHED"}
    assert (scene.render.resolution_x, scene.render.resolution_y) == (32, 18)
    assert (scene.frame_start, scene.frame_end) == (1, 3)
    assert scene.render.fps / scene.render.fps_base == pytest.approx(30)
    bg = scene.camera.data.background_images
    assert len(bg) == 1 and bg[0].image.name == "PlateLight Plate"


def test_static_camera_with_moving_plate_is_reported(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    add_camera(bpy, bpy.context.scene)
    for n in (1, 2):
        png(tmp_path / f"s{n}.png", np.full((18, 32, 3), 90, np.uint8))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "s1.png")) == {"FINISHED"}
    assert "is not animated but the plate has 2 frames" in capfd.readouterr().out


def test_8bit_plate_roundtrips_exactly_next_to_hdr_render(bpy_clean, tmp_path):
    """An 8-bit sRGB plate is read as sRGB (explicitly), composited in linear float with the HDR
    render, and written back as 8-bit sRGB: untouched pixels come back byte for byte."""
    import cv2

    bpy = bpy_clean
    scene = basic_scene(bpy, tmp_path)
    rng = np.random.default_rng(5)
    plate8 = rng.integers(0, 256, (54, 96, 3), dtype=np.uint8)
    png(tmp_path / "plate8.png", plate8)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate8.png")) == {"FINISHED"}
    assert bpy.data.images["PlateLight Plate"].colorspace_settings.name == "sRGB"
    assert bpy.ops.platelight.setup_composite(samples=4) == {"FINISHED"}
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.filepath = str(tmp_path / "out.png")
    bpy.ops.render.render(write_still=True)
    out = cv2.imread(str(tmp_path / "out.png"))[..., ::-1]
    same = np.all(out == plate8, axis=2)
    assert same.mean() > 0.75      # everything but the sphere and its shadow
    assert not same.all()


def test_sequence_frames_keep_their_numbers(bpy_clean, tmp_path):
    """A sequence numbered from 101: scene frame 1 shows file 101, frame 3 shows file 103."""
    bpy = bpy_clean
    scene = basic_scene(bpy, tmp_path, phantoms=False)
    scene.objects["Sphere"].location = (50, -50, 0)  # out of view: the plate everywhere
    frames = {}
    for k, n in enumerate((101, 102, 103)):
        frames[k + 1] = np.full((18, 32, 3), 0.1 + 0.2 * k, np.float32)
        write_exr(tmp_path / f"shot.{n:04d}.exr", frames[k + 1])
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "shot.0101.exr")) == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (1, 3)
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    for frame in (1, 3):
        scene.frame_set(frame)
        out = render(bpy, scene, tmp_path / f"out{frame}.exr")
        np.testing.assert_allclose(out[..., :3], frames[frame], atol=1e-6)


def test_lights_from_bad_probe(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = bpy.context.scene
    write_exr(tmp_path / "square.exr", np.ones((16, 16, 3), np.float32))
    scene.platelight.world_probe = str(tmp_path / "square.exr")
    with pytest.raises(RuntimeError, match="twice as wide"):
        bpy.ops.platelight.lights_from_probe()
    assert "PlateLight Lights" not in bpy.data.collections
    scene.platelight.world_probe = str(tmp_path / "missing.exr")
    with pytest.raises(RuntimeError, match="World probe not found"):
        bpy.ops.platelight.lights_from_probe()


def test_lights_from_probe_rerun_replaces_and_keeps_manual_lights(bpy_clean, studio_hdris):
    bpy = bpy_clean
    scene = bpy.context.scene
    manual = add_sun(bpy, scene)
    scene.platelight.world_probe = str(studio_hdris["sunrise"])
    for count in (8, 4):
        assert bpy.ops.platelight.lights_from_probe(count=count) == {"FINISHED"}
    made = bpy.data.collections["PlateLight Lights"].objects
    assert len(made) == 5 and "PlateLight Sun" in made
    assert manual.name in scene.objects
    sun = made["PlateLight Sun"]
    assert math.degrees(sun.data.angle) < 2.0
    assert not scene.world or not scene.world.cycles_visibility.diffuse


def test_sun_moved_into_a_lamp_and_out_of_the_world(bpy_clean, studio_hdris):
    bpy = bpy_clean
    scene = bpy.context.scene
    env = probe_world(bpy, scene, studio_hdris["sunrise"])
    for _ in range(2):  # a re-run starts again from the probe with its sun
        assert bpy.ops.platelight.lights_from_probe(mode="SUN_SKY") == {"FINISHED"}
    lamps = bpy.data.collections["PlateLight Lights"].objects
    assert [ob.name for ob in lamps] == ["PlateLight Sun"]
    assert env.image.filepath.endswith("sunrise_nosun.exr")
    # an unsaved file keeps it beside Blender's own temporary files, not in a shared folder
    assert bpy.path.abspath(env.image.filepath).startswith(bpy.app.tempdir)
    sky = read_exr(bpy.path.abspath(env.image.filepath))
    assert sky.max() < 0.05 * read_exr(studio_hdris["sunrise"]).max()
    assert scene.platelight.world_probe == str(studio_hdris["sunrise"])
    assert 3.0 < lamps[0].data.energy < 10.0  # sunrise's sun: ~5 W/m² in probe units


def probe_world(bpy, scene, exr, strength=1.0, turn_z=None):
    """A world that shows ``exr`` (times ``strength``), turned about Z by a Mapping node."""
    world = compat().new_world("Probe")
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(exr))
    background = tree.nodes["Background"]
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = strength
    if turn_z is not None:
        mapping = tree.nodes.new("ShaderNodeMapping")
        coords = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, turn_z)
    scene.world = world
    return env


def _lamps(bpy):
    """{name: (direction towards the light, energy)} of the lamps Lights from Probe made."""
    from mathutils import Vector

    return {ob.name: (np.array(ob.rotation_euler.to_matrix() @ Vector((0, 0, 1))), ob.data.energy)
            for ob in bpy.data.collections["PlateLight Lights"].objects}


@pytest.mark.parametrize("mode", ["LIGHTS", "SUN_SKY"])
def test_lights_follow_a_turned_and_brightened_world(bpy_clean, studio_hdris, mode):
    """A Mapping node's quarter turn about Z turns every lamp by it; a Background strength of 2
    doubles their energy (the world shows the image at R·d, so an image direction e is the world
    direction Rᵀe: +X of the image is -Y of the world)."""
    bpy = bpy_clean
    scene = bpy.context.scene
    probe_world(bpy, scene, studio_hdris["sunrise"])
    assert bpy.ops.platelight.lights_from_probe(mode=mode, count=4) == {"FINISHED"}
    plain = _lamps(bpy)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    probe_world(bpy, scene, studio_hdris["sunrise"], strength=2.0, turn_z=math.pi / 2)
    assert bpy.ops.platelight.lights_from_probe(mode=mode, count=4) == {"FINISHED"}
    turned = _lamps(bpy)
    assert sorted(turned) == sorted(plain) and "PlateLight Sun" in turned
    quarter_back = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]])      # Rz(-90°)
    for name, (direction, energy) in plain.items():
        assert np.degrees(np.arccos(min(1.0, turned[name][0] @ (quarter_back @ direction)))) < 0.1, name
        assert turned[name][1] == pytest.approx(2 * energy, rel=1e-4), name


def test_sun_and_sky_needs_an_environment_texture(bpy_clean, studio_hdris):
    bpy = bpy_clean
    scene = bpy.context.scene
    scene.platelight.world_probe = str(studio_hdris["sunrise"])
    with pytest.raises(RuntimeError, match="Environment Texture"):
        bpy.ops.platelight.lights_from_probe(mode="SUN_SKY")
    assert "PlateLight Lights" not in bpy.data.collections


def test_compositing_panel_draws_existing_operators(bpy_clean):
    import importlib

    import support

    bpy = bpy_clean
    panel_module = importlib.import_module(f"{support.EXT_MODULE}.ui.composite_panel")
    assert hasattr(bpy.types, "PLATELIGHT_PT_compositing")

    class Recorder:
        """Stands in for UILayout, which only Blender's window code can create."""
        def __init__(self):
            self.calls = []

        def __getattr__(self, name):
            def call(*args, **kwargs):
                props = type("Props", (), {})()
                self.calls.append((name, args, kwargs, props))
                return self if name in {"column", "row"} else props if name == "operator" else None
            return call

    recorder = Recorder()
    panel_module.PLATELIGHT_PT_compositing.draw(type("P", (), {"layout": recorder})(), bpy.context)
    panel_module.PLATELIGHT_PT_clip_tracking.draw(type("P", (), {"layout": recorder})(), bpy.context)
    ops = [(args[0], vars(props)) for name, args, _, props in recorder.calls if name == "operator"]
    assert len(ops) == 15
    assert ("platelight.setup_composite", {}) in ops        # the default method (AUTO)
    assert {"platelight.track_markers", "platelight.capture_probe", "platelight.setup_lens",
            "platelight.export_farm_job", "platelight.bake_shadows"} <= {idname for idname, _ in ops}
    for idname, settings in ops:
        op = getattr(bpy.ops, idname.split(".")[0])
        rna = getattr(op, idname.split(".")[1]).get_rna_type()
        for key, value in settings.items():  # every preset value is one the operator accepts
            assert value in [item.identifier for item in rna.properties[key].enum_items]
