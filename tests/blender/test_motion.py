"""Moving CG: what moves or deforms over the shot is found, a shadow baked once is never used for
it, and its shadow on a late frame is that frame's (against the analytic shadow of a floating
ball, tests/blender/test_baked_shadows.py)."""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

import composite_scene as cs
from test_baked_shadows import CENTRE, HEIGHT, R, analytic_ratio, floating_black_ball

FRAMES = (1, 8)


def keyed(ob, path, values, frames=FRAMES):
    """Key ``ob``'s ``path`` to each value at each frame."""
    for frame, value in zip(frames, values):
        setattr(ob, path, value)
        ob.keyframe_insert(path, frame=frame)


def box(bpy, scene, name, location, modifiers=()):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], [],
                     [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    scene.collection.objects.link(ob)
    for kind in modifiers:
        ob.modifiers.new(kind.title(), kind)
    return ob


def bulge(ob):
    """A shape key that pulls one corner of the box out over the shot."""
    ob.shape_key_add(name="Basis")
    key = ob.shape_key_add(name="Bulge")
    key.data[7].co = (2, 2, 2)
    for frame, value in zip(FRAMES, (0.0, 1.0)):
        key.value = value
        key.keyframe_insert("value", frame=frame)


def test_every_kind_of_motion_is_found_and_still_objects_are_not(bpy_clean):
    from platelight.operators import motion

    bpy = bpy_clean
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = FRAMES
    still = box(bpy, scene, "Still", (0, 0, 0), modifiers=("SUBSURF",))     # a static modifier
    keys_elsewhere = box(bpy, scene, "Keyed Before The Shot", (3, 0, 0))
    keyed(keys_elsewhere, "location", [(3, 0, 0), (3, 0, 0)], frames=(1, 40))   # a held key
    moved = box(bpy, scene, "Keyed", (0, 3, 0))
    keyed(moved, "location", [(0, 3, 0), (1, 3, 0)])
    turned = box(bpy, scene, "Turned", (0, 6, 0))
    keyed(turned, "rotation_euler", [(0, 0, 0), (0, 0, math.radians(90))])
    parent = bpy.data.objects.new("Parent", None)
    scene.collection.objects.link(parent)
    keyed(parent, "location", [(0, 0, 0), (0, 0, 2)])
    child = box(bpy, scene, "Child", (6, 0, 0))
    child.parent = parent
    leader = bpy.data.objects.new("Leader", None)
    scene.collection.objects.link(leader)
    keyed(leader, "location", [(0, 0, 0), (2, 0, 0)])
    follower = box(bpy, scene, "Constrained", (9, 0, 0))
    follower.constraints.new("COPY_LOCATION").target = leader

    # an armature whose bone turns deforms its mesh; the mesh object itself stays put
    armature = cs.add_armature(bpy, scene, [("Bone", (0, 0, 0), (0, 0, 1), None)])
    skinned = box(bpy, scene, "Skinned", (0, -3, 0))
    group = skinned.vertex_groups.new(name="Bone")
    group.add(range(8), 1.0, "REPLACE")
    skinned.modifiers.new("Armature", "ARMATURE").object = armature
    pose = armature.pose.bones["Bone"]
    pose.rotation_mode = "XYZ"
    for frame, angle in zip(FRAMES, (0.0, 0.7)):
        pose.rotation_euler = (angle, 0, 0)
        pose.keyframe_insert("rotation_euler", frame=frame)

    bulge(box(bpy, scene, "Shape Keys", (0, -6, 0)))

    displaced = box(bpy, scene, "Displaced", (0, -9, 0), modifiers=("DISPLACE",))
    for frame, value in zip(FRAMES, (0.0, 0.5)):
        displaced.modifiers["Displace"].strength = value
        displaced.modifiers["Displace"].keyframe_insert("strength", frame=frame)

    walking = box(bpy, scene, "Walking", (0, -12, 0))        # moves and deforms
    keyed(walking, "location", [(0, -12, 0), (1, -12, 0)])
    bulge(walking)

    scene.frame_set(3)
    objects = [ob for ob in scene.objects if ob.type == "MESH"]
    found = motion.motions(scene, objects)
    assert {name: m.kind for name, m in found.items()} == {
        "Keyed": "moves", "Turned": "moves", "Child": "moves", "Constrained": "moves", "Walking": "moves",
        "Skinned": "deforms", "Shape Keys": "deforms", "Displaced": "deforms"}
    # asked for shapes only, what moves and deforms deforms, what only moves is not there
    assert set(motion.motions(scene, objects, kinds=("deforms",))) == {"Skinned", "Shape Keys", "Displaced", "Walking"}
    assert scene.frame_current == 3                     # the user's frame is kept
    assert "'Skinned' deforms during the shot" in found["Skinned"].sentence()
    # a shot that ends before the keys change sees nothing move
    scene.frame_end = 1
    assert motion.motions(scene, objects) == {}


def animate_ball(scene, ball, frame_end=FRAMES[1], to_x=1.5):
    scene.frame_start, scene.frame_end = FRAMES[0], frame_end
    keyed(ball, "location", [tuple(CENTRE), (CENTRE[0] + to_x, CENTRE[1], CENTRE[2])], (FRAMES[0], frame_end))
    scene.frame_set(FRAMES[0])


def test_a_ball_animated_after_the_bake_gets_each_frames_own_shadow(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert bpy.ops.platelight.bake_shadows(height=64, samples=8) == {"FINISHED"}
    # animated after the bake: on frame 1 it is where the bake saw it, so the bake's hash still fits
    animate_ball(scene, ball)
    capfd.readouterr()

    # the bake by name cannot serve it: one sentence, nothing set up
    layers = sorted(layer.name for layer in scene.view_layers)
    with pytest.raises(RuntimeError, match="'Sphere' moves during the shot .from frame 2.*cannot follow it"):
        bpy.ops.platelight.setup_composite(method="BAKED")
    assert sorted(layer.name for layer in scene.view_layers) == layers and not floor.is_shadow_catcher

    # the default path-traces its shadows every frame, and says why
    assert bpy.ops.platelight.setup_composite(samples=64) == {"FINISHED"}
    said = capfd.readouterr().out
    assert "(catcher, cycles)" in said and "'Sphere' moves during the shot" in said
    assert floor.is_shadow_catcher

    # frame 8: the shadow is the ball's there, not where it was baked
    scene.frame_set(FRAMES[1])
    check_frame_shadow(bpy, scene, ball, tmp_path / "out", 35)

    # baked again, the ball's shadows are baked at every frame and only looked up
    per_frame = dict(height=128, samples=16, moving_shadows="PER_FRAME", moving_height=128)
    assert bpy.ops.platelight.bake_shadows(**per_frame) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=64) == {"FINISHED"}
    assert "(baked, cycles)" in capfd.readouterr().out and not floor.is_shadow_catcher
    scene.frame_set(FRAMES[1])
    check_frame_shadow(bpy, scene, ball, tmp_path / "baked", 35)

    # the per-frame files: a frame's file gone is baked again; a shorter shot leaves no old
    # frame's files behind; a refused bake (the lone moving ball left to the catcher) keeps them
    from platelight.addon.compositing import baked_shadows as engine
    from platelight.operators.baked_shadows import shadows_folder

    moving = pathlib.Path(shadows_folder(scene)) / engine.MOVING_FOLDER

    def frames_on_disk():
        return sorted({int(n.stem[-4:]) for n in moving.glob("*.exr")})

    assert frames_on_disk() == list(range(FRAMES[0], FRAMES[1] + 1))
    (moving / engine.ratio_filename(3)).unlink()
    assert bpy.ops.platelight.bake_shadows(**per_frame) == {"FINISHED"}
    assert (moving / engine.ratio_filename(3)).is_file()
    scene.frame_end = 5
    assert bpy.ops.platelight.bake_shadows(**per_frame) == {"FINISHED"}
    assert frames_on_disk() == list(range(FRAMES[0], 6))
    with pytest.raises(RuntimeError, match="need at least one CG object"):
        bpy.ops.platelight.bake_shadows(moving_shadows="CATCHER")
    assert frames_on_disk() == list(range(FRAMES[0], 6))


def check_frame_shadow(bpy, scene, ball, folder, least_psnr):
    """The ratio under ``ball`` on this frame against the analytic shadow of it there."""
    _image, passes = cs.render_with_passes(bpy, scene, folder)
    ground, origin, rays = cs.ground_points(bpy, scene)
    centre = np.array(ball.matrix_world.translation)
    assert abs(centre[0] - CENTRE[0] - 1.5) < 1e-6
    visible = np.isfinite(ground).all(axis=-1) & ~cs.sphere_hit(origin, rays, centre, R, margin=0.05)
    near = visible & (np.linalg.norm(ground[..., :2] - centre[:2], axis=-1) < 2.0)
    ratio = passes["Shadows"][..., :3].mean(axis=-1)
    expected, stale = analytic_ratio(ground, centre), analytic_ratio(ground, CENTRE)
    assert near.sum() > 300
    error = np.abs(ratio[near] - expected[near])
    assert np.median(error) < 0.02, np.median(error)
    # contact darkening: the darkest point under the ball
    assert abs(float(np.percentile(ratio[near], 1)) - float(np.percentile(expected[near], 1))) < 0.05
    # shadow PSNR of plate x ratio against plate x analytic ratio (peak: the plate's brightest)
    plate = cs.read_exr(folder.parent / "plate.exr", "RGB").mean(axis=-1)
    mse = np.mean((plate[near] * (ratio[near] - expected[near])) ** 2)
    assert 10 * np.log10(plate.max() ** 2 / mse) >= least_psnr
    # the stale shadow would be far off
    assert np.median(np.abs(stale[near] - expected[near])) > 3 * np.median(error)


def test_moving_cg_refuses_a_bake_and_eevee_motion_blur_in_one_sentence(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene, floor, ball = floating_black_ball(bpy, tmp_path)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    animate_ball(scene, ball)
    with pytest.raises(RuntimeError, match="'Sphere' moves during the shot .from frame 2.: baked shadows "
                       "need at least one CG object .or Moving CG: Baked Every Frame. that stand still"):
        bpy.ops.platelight.bake_shadows(height=32, samples=2, moving_shadows="CATCHER")
    assert not (tmp_path / "maps" / "_shadows").exists()

    scene.render.use_motion_blur = True
    layers = sorted(layer.name for layer in scene.view_layers)
    with pytest.raises(RuntimeError, match="EEVEE's composite does not blur the shadows"):
        bpy.ops.platelight.setup_composite(engine="EEVEE")
    assert sorted(layer.name for layer in scene.view_layers) == layers and scene.render.use_motion_blur
    # Cycles blurs the CG and the shadow catcher's pass together
    assert bpy.ops.platelight.setup_composite() == {"FINISHED"}
    assert floor.is_shadow_catcher


STILL, ROLL_FROM, ROLL_TO = np.array([-1.2, 0.0, HEIGHT]), np.array([1.2, -1.0, HEIGHT]), np.array([1.2, 1.0, HEIGHT])


@pytest.mark.parametrize("moving_shadows, route", [("PER_FRAME", "baked"), ("CATCHER", "mixed")])
def test_a_still_ball_keeps_its_baked_shadow_while_a_moving_one_gets_each_frames(bpy_clean, tmp_path, capfd,
                                                                                 moving_shadows, route):
    """The moving ball's shadows baked at each frame, or caught every frame by a catcher layer of
    their own; either way times the still ball's baked once."""
    from bake_scenes import probe_renders
    from platelight.operators import baked_shadows

    bpy = bpy_clean
    scene, floor, still = floating_black_ball(bpy, tmp_path, save=False)
    still.location = tuple(STILL)
    rolling = cs.add_sphere(bpy, scene, location=tuple(ROLL_FROM), radius=R, name="Rolling")
    rolling.data.materials.append(still.data.materials[0])
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    scene.frame_start, scene.frame_end = FRAMES       # the still plate held over the shot
    keyed(rolling, "location", [tuple(ROLL_FROM), tuple(ROLL_TO)])
    scene.frame_set(FRAMES[0])
    capfd.readouterr()
    renders = probe_renders()
    assert bpy.ops.platelight.bake_shadows(height=64, samples=8, moving_shadows=moving_shadows, moving_height=64) == {"FINISHED"}
    said = capfd.readouterr().out
    assert "'Rolling' moves during the shot (from frame 2): its shadow is left out of the bake of the still CG" in said
    per_frame = moving_shadows == "PER_FRAME"
    assert ("it is baked at each of the shot's frames" in said) == per_frame
    # the still panorama, and one a frame of the rolling ball's
    assert probe_renders() - renders == 1 + (FRAMES[1] - FRAMES[0] + 1 if per_frame else 0)
    # current on the last frame too: the moving ball's place counts only where baked per frame
    scene.frame_set(FRAMES[1])
    assert baked_shadows.baked_is_current(scene)
    renders = probe_renders()
    assert bpy.ops.platelight.bake_shadows(height=64, samples=8, moving_shadows=moving_shadows, moving_height=64) == {"FINISHED"}
    assert probe_renders() == renders

    assert bpy.ops.platelight.setup_composite(samples=64) == {"FINISHED"}
    said = capfd.readouterr().out
    assert f"({route}, cycles)" in said and "WARNING" not in said
    used = {layer.name for layer in scene.view_layers if layer.use}
    if per_frame:
        assert used == {"PlateLight CG", "PlateLight Shadows"}, used
    else:
        assert "the shadows of 1 moving CG object(s) rendered every frame" in said
        assert used == {"PlateLight CG", "PlateLight Shadows", "PlateLight Moving Shadows"}, used
        assert [ob.name for ob in bpy.data.collections["PlateLight Moving CG"].objects] == ["Rolling"]

    _image, passes = cs.render_with_passes(bpy, scene, tmp_path / "out")
    ground, origin, rays = cs.ground_points(bpy, scene)
    rolled = np.array(rolling.matrix_world.translation)
    assert np.allclose(rolled, ROLL_TO)
    visible = np.isfinite(ground).all(axis=-1)
    for centre in (STILL, rolled, ROLL_FROM):
        visible &= ~cs.sphere_hit(origin, rays, centre, R, margin=0.05)
    ratio = passes["Shadows"][..., :3].mean(axis=-1)
    expected = analytic_ratio(ground, STILL) * analytic_ratio(ground, rolled)
    plate = cs.read_exr(tmp_path / "plate.exr", "RGB").mean(axis=-1)
    for centre in (STILL, rolled):
        near = visible & (np.linalg.norm(ground[..., :2] - centre[:2], axis=-1) < 1.5)
        assert near.sum() > 200
        error = np.abs(ratio[near] - expected[near])
        assert np.median(error) < 0.02, (centre, np.median(error))
        # contact darkening: the darkest point under each ball
        assert abs(float(np.percentile(ratio[near], 1)) - float(np.percentile(expected[near], 1))) < 0.05
        mse = np.mean((plate[near] * (ratio[near] - expected[near])) ** 2)
        assert 10 * np.log10(plate.max() ** 2 / mse) >= 35
    # where the rolling ball was on frame 1 the floor is lit again (no stale shadow)
    was = visible & (np.linalg.norm(ground[..., :2] - ROLL_FROM[:2], axis=-1) < 0.6)
    assert was.sum() > 20
    stale = analytic_ratio(ground, STILL) * analytic_ratio(ground, ROLL_FROM)
    assert np.median(np.abs(ratio[was] - expected[was])) < 0.25 * np.median(np.abs(stale[was] - expected[was]))

    # the rolling ball keyed elsewhere after the bake: a bake per frame no longer fits
    keyed(rolling, "location", [tuple(ROLL_FROM), tuple(ROLL_TO + np.array([0.0, 0.5, 0.0]))])
    assert baked_shadows.baked_is_current(scene) is (not per_frame)


def test_a_single_frame_probe_bake_says_what_moves(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    scene, _floor, ball = floating_black_ball(bpy, tmp_path)
    scene.platelight.probe_height, scene.platelight.probe_samples = 16, 2
    ball.platelight.enabled = True
    rolling = cs.add_sphere(bpy, scene, location=tuple(ROLL_FROM), radius=R, name="Rolling")
    scene.frame_start, scene.frame_end = FRAMES
    keyed(rolling, "location", [tuple(ROLL_FROM), tuple(ROLL_TO)])
    scene.frame_set(FRAMES[0])
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}
    said = capfd.readouterr().out
    assert ("'Rolling' moves during the shot (from frame 2): these probes hold the scene as it is at "
            "frame 1; bake the frame range") in said
    # Frame Range alone bakes the scene's range: a probe a frame, and nothing more to say
    scene.frame_end = 3
    assert bpy.ops.platelight.bake_probes(all_objects=True, use_frame_range=True) == {"FINISHED"}
    assert "these probes hold" not in capfd.readouterr().out
    assert sorted(p.name for p in (tmp_path / "maps" / "Sphere").glob("diffuse_0*.exr")) == [
        "diffuse_0001.exr", "diffuse_0002.exr", "diffuse_0003.exr"]


def sunlit(ground, centre, towards_sun):
    """1 where a floor point sees the sun past a ball at ``centre``, else 0."""
    offset = centre - ground
    along = offset @ towards_sun
    across = np.linalg.norm(offset - along[..., None] * towards_sun, axis=-1)
    return np.where((along > 0) & (across < R), 0.0, 1.0)


def test_motion_blur_blurs_a_moving_ball_s_shadow_as_the_shutter_sweeps_it(bpy_clean, tmp_path, capfd):
    """Under a hard sun in a black sky, with Motion Blur, a rolling ball's shadow is the fraction
    of the shutter's positions of the ball from which the floor point sees the sun; a per-frame
    bake, whose shadow would stay sharp, is passed over."""
    from platelight.node_groups._build import action_fcurves

    bpy = bpy_clean
    scene, _floor, still = floating_black_ball(bpy, tmp_path, save=False)
    cs.grey_world(bpy, scene, 0.0)
    towards_sun = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)     # the shadows fall 1 m towards the camera
    cs.add_sun(bpy, scene, towards_sun, strength=3.0)
    still.location = tuple(STILL)
    rolling = cs.add_sphere(bpy, scene, location=(0.0, 0.8, HEIGHT), radius=R, name="Rolling")
    rolling.data.materials.append(still.data.materials[0])
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    scene.frame_start, scene.frame_end = 1, 3
    keyed(rolling, "location", [(0.0, 0.8, HEIGHT), (2.4, 0.8, HEIGHT)], frames=(1, 3))   # 1.2 m a frame
    for curve in action_fcurves(rolling):
        for point in curve.keyframe_points:
            point.interpolation = "LINEAR"
    scene.frame_set(1)
    scene.render.use_motion_blur = True
    shutter = scene.render.motion_blur_shutter              # centred on the frame (Blender's default)

    assert bpy.ops.platelight.bake_shadows(height=64, samples=8, moving_shadows="PER_FRAME", moving_height=64) == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite(samples=64) == {"FINISHED"}
    said = capfd.readouterr().out
    assert "(catcher, cycles)" in said and "Motion Blur is on, and the shadows baked at each frame" in said

    assert bpy.ops.platelight.bake_shadows(height=64, samples=8, moving_shadows="CATCHER") == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.platelight.setup_composite(samples=64) == {"FINISHED"}
    said = capfd.readouterr().out
    assert "(mixed, cycles)" in said and "WARNING" not in said

    scene.frame_set(2)
    _image, passes = cs.render_with_passes(bpy, scene, tmp_path / "out")
    ground, origin, rays = cs.ground_points(bpy, scene)
    swept = [np.array([1.2 * (t - 1), 0.8, HEIGHT]) for t in np.linspace(2 - shutter / 2, 2 + shutter / 2, 65)]
    visible = np.isfinite(ground).all(axis=-1) & ~cs.sphere_hit(origin, rays, STILL, R, margin=0.05)
    for centre in swept[::8]:
        visible &= ~cs.sphere_hit(origin, rays, centre, R, margin=0.05)
    ratio = passes["Shadows"][..., :3].mean(axis=-1)
    still_lit = sunlit(ground, STILL, towards_sun)
    blurred = still_lit * np.mean([sunlit(ground, c, towards_sun) for c in swept], axis=0)
    sharp = still_lit * sunlit(ground, swept[32], towards_sun)
    # where the blur changes the shadow, away from its analytic edges' pixel
    swept_region = visible & (np.abs(blurred - sharp) > 0.1)
    assert swept_region.sum() > 100, swept_region.sum()
    error = np.abs(ratio - blurred)[swept_region]
    assert np.median(error) < 0.05, np.median(error)
    assert np.median(error) < 0.3 * np.median(np.abs(ratio - sharp)[swept_region])
