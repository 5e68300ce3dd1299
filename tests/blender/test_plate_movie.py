"""Movie-file plates (setup_plate with an .avi/.mp4 written here by OpenCV, read by Blender's own
FFmpeg): scene size, frame range, frame rate (integer and NTSC 23.976), camera background, the
plate image, re-running, the plate pixels of each frame in a rendered composite, bad files."""
import numpy as np
import pytest

import support  # noqa: F401
from composite_scene import add_camera, add_sphere, add_sun, grey_world
from test_composite_inputs import scene_state

W, H, FRAMES = 64, 36, 6


def frame_image(k):
    """Frame k (1-based) of the test movie, RGB uint8: a flat colour that changes with k and a
    white block whose position changes with k (distinct content in every frame)."""
    img = np.empty((H, W, 3), np.uint8)
    img[:] = (30 + 35 * k, 220 - 30 * k, 60 + 20 * (k % 3))
    x = 4 + 9 * (k - 1)
    img[8:24, x:x + 8] = 235
    return img


def write_movie(path, fourcc, fps, frames=FRAMES):
    import cv2

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (W, H))
    assert writer.isOpened(), f"this OpenCV cannot write {fourcc} to {path.suffix}"
    for k in range(1, frames + 1):
        writer.write(np.ascontiguousarray(frame_image(k)[..., ::-1]))
    writer.release()
    return path


def decoded_frames(path):
    """The movie's frames as OpenCV's FFmpeg decodes them (RGB uint8): the lossy codec's truth."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(bgr[..., ::-1].copy())
    return out


def full_state(bpy):
    state = scene_state(bpy)
    scene = bpy.context.scene
    state["movieclips"] = sorted(c.name for c in bpy.data.movieclips)
    state["backgrounds"] = [(b.image.name if b.image else None) for b in scene.camera.data.background_images]
    state["colour"] = (scene.view_settings.look, scene.view_settings.exposure, scene.render.dither_intensity)
    return state


@pytest.mark.parametrize("suffix, fourcc, fps, fps_pair", [
    (".avi", "MJPG", 12.0, (12, 1.0)),
    (".mp4", "mp4v", 24000 / 1001, (24, 1.001)),
])
def test_movie_plate_matches_the_scene(bpy_clean, tmp_path, suffix, fourcc, fps, fps_pair):
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    movie = write_movie(tmp_path / f"shot{suffix}", fourcc, fps)
    for _ in range(2):   # re-running updates in place
        assert bpy.ops.platelight.setup_plate(filepath=str(movie)) == {"FINISHED"}
    render = scene.render
    assert (render.resolution_x, render.resolution_y, render.resolution_percentage) == (W, H, 100)
    assert (scene.frame_start, scene.frame_end) == (1, FRAMES)
    assert render.fps / render.fps_base == pytest.approx(fps, abs=1e-4)
    assert (render.fps, render.fps_base) == (fps_pair[0], pytest.approx(fps_pair[1], abs=1e-6))
    plates = [i for i in bpy.data.images if i.filepath and i.source == "MOVIE"]
    assert [i.name for i in bpy.data.images] == ["PlateLight Plate"] and len(plates) == 1
    plate = plates[0]
    assert bpy.path.abspath(plate.filepath) == str(movie)
    assert plate.colorspace_settings.name == "sRGB" and tuple(plate.size) == (W, H)
    assert len(bpy.data.movieclips) == 0          # the probe clip is not left behind
    backgrounds = scene.camera.data.background_images
    assert len(backgrounds) == 1 and backgrounds[0].image == plate
    assert backgrounds[0].image_user.frame_duration == FRAMES
    assert scene.camera.data.show_background_images
    assert scene.view_settings.view_transform == "Standard"


def test_movie_frame_k_is_plate_frame_k(bpy_clean, tmp_path):
    """Render the composite of frames 1, 4 and 6 (a CG sphere out of view: the plate everywhere)
    as 8-bit PNG and compare with the movie's decoded frames."""
    import cv2

    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    add_sphere(bpy, scene, location=(50, -50, 0))
    add_sun(bpy, scene)
    grey_world(bpy, scene, 0.0)
    movie = write_movie(tmp_path / "shot.avi", "MJPG", 12.0)
    truth = decoded_frames(movie)
    assert len(truth) == FRAMES
    assert bpy.ops.platelight.setup_plate(filepath=str(movie)) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "PNG", "8", "RGB"
    for k in (1, 4, 6):
        scene.frame_set(k)
        scene.render.filepath = str(tmp_path / f"out{k}.png")
        bpy.ops.render.render(write_still=True)
        out = cv2.imread(str(tmp_path / f"out{k}.png"))[..., ::-1].astype(int)
        errors = [np.abs(out - t.astype(int)).mean() for t in truth]
        assert int(np.argmin(errors)) == k - 1, (k, errors)
        assert errors[k - 1] < 2.0 and np.abs(out - truth[k - 1].astype(int)).max() <= 12, (k, errors)


@pytest.mark.parametrize("content", [b"", b"random"])
def test_corrupt_movie_is_refused_and_scene_kept(bpy_clean, tmp_path, content):
    bpy = bpy_clean
    add_camera(bpy, bpy.context.scene)
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(np.random.default_rng(1).bytes(20000) if content else b"")
    before = full_state(bpy)
    with pytest.raises(RuntimeError) as err:
        bpy.ops.platelight.setup_plate(filepath=str(bad))
    message = str(err.value).strip().splitlines()[-1]
    assert "cannot read" in message and str(bad) in message and message.count(". ") == 0, message
    assert full_state(bpy) == before


def test_movie_replaces_a_sequence_plate_and_missing_movie_is_refused(bpy_clean, tmp_path):
    """A movie after an image sequence: the one plate image becomes the movie (the compositor's
    and the background's references follow it); then a missing movie changes nothing."""
    import cv2

    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    for n in (1, 2, 3):
        assert cv2.imwrite(str(tmp_path / f"seq_{n:04d}.png"), np.full((18, 32, 3), 50 * n, np.uint8))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "seq_0001.png"), fps=30) == {"FINISHED"}
    movie = write_movie(tmp_path / "shot.avi", "MJPG", 12.0)
    assert bpy.ops.platelight.setup_plate(filepath=str(movie)) == {"FINISHED"}
    assert [(i.name, i.source) for i in bpy.data.images] == [("PlateLight Plate", "MOVIE")]
    assert (scene.frame_end, scene.render.resolution_x, scene.render.fps, scene.render.fps_base) == (FRAMES, W, 12, 1.0)
    backgrounds = scene.camera.data.background_images
    assert len(backgrounds) == 1 and backgrounds[0].image.source == "MOVIE"
    before = full_state(bpy)
    with pytest.raises(RuntimeError, match="Plate file not found"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "gone.mp4"))
    assert full_state(bpy) == before
