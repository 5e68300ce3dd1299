"""bpy.ops.platelight.track_markers and bpy.ops.platelight.capture_probe in headless Blender:
they write the camera, the phantom plane and the world probe; on bad input they report one
sentence, cancel, and leave the scene as it was."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

import capture_render as cr
from platelight.addon.capture import mirror_ball
from platelight.addon.capture.boards import write_target
from platelight.addon.capture.poses import rotation_error_deg
from platelight.addon.capture.targets import MarkerTarget
from platelight.addon.exr_io import read_exr
from support import compat
from test_capture_probe import brackets, forward_ball, smooth_env

FRAMES = 4


@pytest.fixture(scope="module")
def marker_clip(bpy_module, tmp_path_factory):
    folder = tmp_path_factory.mktemp("op_track")
    target = MarkerTarget("DICT_4X4_50", 0.12)
    write_target(folder / "marker.png", target, dpi=cr.PX_PER_M * 0.0254, margin_m=cr.MARGIN_M)
    poses = cr.camera_path(FRAMES, 0.5, seed=11)
    cr.render_target_frames(bpy_module, folder / "marker.png", target.extent, poses, folder / "frames",
                            samples=8, lens_mm=30.0)
    return folder / "frames", poses


def _scene_state(bpy):
    scene = bpy.context.scene
    return (sorted(o.name for o in bpy.data.objects), scene.camera.name if scene.camera else None,
            scene.world.name if scene.world else None, scene.platelight.world_probe,
            scene.render.resolution_x, scene.frame_end, len(bpy.data.actions))


def test_track_markers_keys_camera_and_adds_phantom(bpy_clean, marker_clip):
    bpy = bpy_clean
    frames, poses = marker_clip
    scene = bpy.context.scene
    scene.frame_start = 10
    result = bpy.ops.platelight.track_markers(filepath=str(frames), marker_size=0.12, focal_mm=30.0,
                                              sensor_mm=36.0)
    assert result == {"FINISHED"}
    camera = scene.camera
    assert camera is not None and camera.data.lens == pytest.approx(30.0, rel=1e-6)
    assert (scene.render.resolution_x, scene.render.resolution_y) == (640, 480)
    assert scene.frame_end == 10 + FRAMES - 1
    for i, truth in enumerate(poses):
        scene.frame_set(10 + i)
        m = np.array(camera.matrix_world)
        assert rotation_error_deg(m, truth) < 0.2
        assert np.linalg.norm(m[:3, 3] - truth[:3, 3]) < 0.002
    plane = bpy.data.objects["PlateLight Marker Plane"]
    assert plane.platelight.phantom is True
    assert tuple(plane.dimensions)[:2] == pytest.approx((0.12, 0.12))
    # running it again updates, never duplicates
    assert bpy.ops.platelight.track_markers(filepath=str(frames), marker_size=0.12, focal_mm=30.0,
                                            sensor_mm=36.0) == {"FINISHED"}
    assert sum(o.name.startswith("PlateLight Marker Plane") for o in bpy.data.objects) == 1
    assert sum(1 for o in bpy.data.objects if o.type == "CAMERA") == 1


def test_track_markers_failure_leaves_scene_unchanged(bpy_clean, tmp_path):
    bpy = bpy_clean
    for i in range(2):
        cv2.imwrite(str(tmp_path / f"{i}.png"), np.full((60, 80), 200, np.uint8))
    before = _scene_state(bpy)
    with pytest.raises(RuntimeError, match="No DICT_4X4_50 marker was found in any of the 2 frames"):
        bpy.ops.platelight.track_markers(filepath=str(tmp_path), marker_size=0.1, focal_mm=30.0)
    with pytest.raises(RuntimeError, match="Frames not found"):
        bpy.ops.platelight.track_markers(filepath=str(tmp_path / "missing"), marker_size=0.1)
    with pytest.raises(RuntimeError, match="no movie clip"):
        bpy.ops.platelight.track_markers()
    assert _scene_state(bpy) == before


@pytest.fixture(scope="module")
def ball_photos(tmp_path_factory):
    folder = tmp_path_factory.mktemp("op_ball")
    env = smooth_env(64)
    photo = forward_ball(env, 160, 70.0, mirror_ball.default_camera_rotation(), background=0.05)
    names = []
    for i, img in enumerate(brackets(photo, [1 / 500, 1 / 125, 1 / 30, 1 / 8], scale=2.0)):
        names.append(f"b{i}.png")
        cv2.imwrite(str(folder / names[-1]), img)
    return folder, names, env


def test_capture_probe_sets_world(bpy_clean, ball_photos, tmp_path):
    bpy = bpy_clean
    folder, names, env = ball_photos
    out = tmp_path / "world.exr"
    result = bpy.ops.platelight.capture_probe(directory=str(folder), files=[{"name": n} for n in names],
                                              exposures="1/500,1/125,1/30,1/8", height=32, output=str(out))
    assert result == {"FINISHED"}
    scene = bpy.context.scene
    assert scene.platelight.world_probe == str(out)
    node = scene.world.node_tree.nodes["PlateLight Probe"]
    assert node.type == "TEX_ENVIRONMENT" and bpy.path.abspath(node.image.filepath) == str(out)
    background = next(n for n in scene.world.node_tree.nodes if n.type == "BACKGROUND")
    assert background.inputs["Color"].links[0].from_node == node
    probe = read_exr(out)
    assert probe.shape == (32, 64, 3)
    # a second run with a rotation reuses the node and turns the probe by a quarter
    result = bpy.ops.platelight.capture_probe(directory=str(folder), files=[{"name": n} for n in names],
                                              exposures="1/500,1/125,1/30,1/8", height=32, output=str(out),
                                              rotate_z=math.radians(90))
    assert result == {"FINISHED"}
    assert sum(1 for n in scene.world.node_tree.nodes if n.type == "TEX_ENVIRONMENT") == 1
    assert np.allclose(np.roll(probe, -16, axis=1), read_exr(out), rtol=1e-4, atol=1e-6)


def test_captured_probe_lights_the_bake_as_the_turned_brightened_world_shows_it(bpy_clean, ball_photos,
                                                                               tmp_path):
    """The probe goes into the world's probe node, which keeps its Mapping (a quarter turn) and
    the Background its strength (2): the world maps follow both, as Cycles shows the world."""
    from bake_scenes import add_sphere, read_map
    from platelight.addon import names
    from platelight.addon.ibl.maps import MapSettings, compute_maps

    bpy = bpy_clean
    folder, photo_names, _ = ball_photos
    scene = bpy.context.scene
    scene.world = compat().new_world("Set")
    tree = scene.world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.name = names.WORLD_PROBE_NODE
    mapping = tree.nodes.new("ShaderNodeMapping")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    tree.nodes["Background"].inputs["Strength"].default_value = 2.0
    scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(scene.camera)
    scene.camera.location = (0.0, -10.0, 0.0)
    scene.camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    out = tmp_path / "world.exr"
    assert bpy.ops.platelight.capture_probe(directory=str(folder), files=[{"name": n} for n in photo_names],
                                            exposures="1/500,1/125,1/30,1/8", height=32,
                                            output=str(out)) == {"FINISHED"}
    add_sphere(bpy, "Alone", (0, 0, 0))                # sees only the world: the world maps
    assert bpy.ops.platelight.bake_probes(all_objects=True, cull=False) == {"FINISHED"}
    probe = read_exr(out)
    turned = compute_maps(np.roll(probe, probe.shape[1] // 4, axis=1), MapSettings(), which=("diffuse",))
    np.testing.assert_allclose(read_map(tmp_path, "_world", "diffuse"), 2 * turned.maps["diffuse"],
                               rtol=1e-4, atol=1e-6)
    unturned = compute_maps(probe, MapSettings(), which=("diffuse",)).maps["diffuse"]
    assert np.abs(unturned - turned.maps["diffuse"]).max() > 0.1 * unturned.max()   # the turn shows


def test_capture_probe_unsure_ball_is_shown_with_its_circles(bpy_clean, tmp_path):
    """A ball found on little of its rim (a corpus photo: a bright sky behind, a stand): the
    probe is made, and the photo with the circle used is an image to check it on."""
    import ball_corpus as bc

    bpy = bpy_clean
    spec = bc.Spec("overcast", 1200, 900, 0.52, (-0.5, -0.85), reflectance=0.885, backdrop="bright",
                   holder="stand", exposure=1, jpeg=75, yaw=220)
    photo, truth, _ = bc.render(spec, seed=21)
    cv2.imwrite(str(tmp_path / "ball.png"), photo)
    result = bpy.ops.platelight.capture_probe(directory=str(tmp_path), files=[{"name": "ball.png"}], height=32)
    assert result == {"FINISHED"}
    image = bpy.data.images["PlateLight Ball Candidates"]
    w, h = image.size
    assert (w, h) == (1200, 900)
    rgba = np.array(image.pixels[:]).reshape(h, w, 4)[::-1]
    green = (rgba[..., 1] > 0.7) & (rgba[..., 0] < 0.47) & (rgba[..., 2] < 0.47)
    ys, xs = np.nonzero(green)
    ring = np.hypot(xs - truth["cx"], ys - truth["cy"]) / (0.5 * (truth["rx"] + truth["ry"]))
    assert green.sum() > 500 and (np.abs(ring - 1) < 0.03).mean() > 0.7


def test_capture_probe_failure_leaves_scene_unchanged(bpy_clean, ball_photos, tmp_path):
    bpy = bpy_clean
    folder, names, _ = ball_photos
    before = _scene_state(bpy)
    # one photo is a valid input, but this one shows no ball (a grey ramp and a box); the
    # sentence names the operator's field, not the CLI's flag
    blank = np.repeat(np.linspace(40, 200, 160, dtype=np.float32)[None, :, None], 3, axis=2)
    blank = np.repeat(blank, 120, axis=0)
    blank[30:80, 50:130] = 20
    cv2.imwrite(str(tmp_path / "blank.png"), blank.astype(np.uint8))
    with pytest.raises(RuntimeError, match="No mirror ball was found in the photo; give its circle with the Ball Circle field"):
        bpy.ops.platelight.capture_probe(directory=str(tmp_path), files=[{"name": "blank.png"}])
    assert not (tmp_path / "probe.exr").exists()
    with pytest.raises(RuntimeError, match="No EXIF exposure time") as refused:
        bpy.ops.platelight.capture_probe(directory=str(folder), files=[{"name": n} for n in names])
    # Blender's words: the operator's field, not the command line's flag
    assert "the Exposure Times field" in str(refused.value) and "--" not in str(refused.value)
    with pytest.raises(RuntimeError, match="ball circle needs 3"):
        bpy.ops.platelight.capture_probe(directory=str(folder), files=[{"name": n} for n in names],
                                         exposures="1/500,1/125,1/30,1/8", ball="1,2")
    assert _scene_state(bpy) == before
    assert not (folder / "probe.exr").exists()


def test_track_markers_calibration_sets_shift_and_pixel_aspect(bpy_clean, marker_clip, tmp_path):
    """A calibrated principal point becomes the camera's shift; fx != fy a pixel aspect."""
    import json

    bpy = bpy_clean
    frames, _ = marker_clip
    f = 30.0 * 640 / 36
    calib = tmp_path / "calib.json"
    calib.write_text(json.dumps({"intrinsics": {"fx": f, "fy": 1.1 * f, "cx": 329.5, "cy": 229.5}}))
    assert bpy.ops.platelight.track_markers(filepath=str(frames), marker_size=0.12, calibration=str(calib),
                                            sensor_mm=36.0) == {"FINISHED"}
    scene = bpy.context.scene
    cam = scene.camera.data
    assert cam.lens == pytest.approx(30.0)
    assert cam.shift_x == pytest.approx(-10 / 640) and cam.shift_y == pytest.approx(-10 / 640)
    assert scene.render.pixel_aspect_x == pytest.approx(1.1) and scene.render.pixel_aspect_y == 1.0


def test_track_markers_defaults_to_the_active_movie_clip(bpy_clean, marker_clip):
    bpy = bpy_clean
    frames, poses = marker_clip
    clip = bpy.data.movieclips.load(str(frames / "0001.png"))
    bpy.context.scene.active_clip = clip
    assert clip.source == "SEQUENCE"
    assert bpy.ops.platelight.track_markers(marker_size=0.12, focal_mm=30.0, sensor_mm=36.0) == {"FINISHED"}
    scene = bpy.context.scene
    scene.frame_set(scene.frame_start + FRAMES - 1)
    assert rotation_error_deg(np.array(scene.camera.matrix_world), poses[-1]) < 0.2


def test_capture_probe_grey_card_repair(bpy_clean, tmp_path):
    from test_capture_probe import sun_and_card_photos

    bpy = bpy_clean
    paths, cosine, irradiance, _ = sun_and_card_photos(tmp_path)
    out = tmp_path / "repaired.exr"
    assert bpy.ops.platelight.capture_probe(directory=str(tmp_path), files=[{"name": p.name} for p in paths],
                                            exposures="1/500,1/125,1/30,1/8", height=64, ball="99.5,99.5,90",
                                            grey_card="220,20,260,60", output=str(out)) == {"FINISHED"}
    lit = np.einsum("hw,hwc->c", cosine, read_exr(out).astype(np.float64)) * (128 / 255) ** 2.2 / 2.0
    assert np.allclose(lit, irradiance, rtol=0.03)
    with pytest.raises(RuntimeError, match="grey card box needs 4"):
        bpy.ops.platelight.capture_probe(directory=str(tmp_path), files=[{"name": p.name} for p in paths],
                                         exposures="1/500,1/125,1/30,1/8", grey_card="1,2,3")
