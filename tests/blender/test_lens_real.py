"""Lens distortion on real photos, end to end: the four OpenCV tutorial webcam photos as a plate,
tracked with OpenCV's calibration of them (k1..k3 and both tangential terms), composited with
small CG squares placed on board corners: each square lands on the corner OpenCV detects in the
real photo."""
import shutil

import numpy as np

import support  # noqa: F401
from support import compat
from platelight.addon.capture.targets import CharucoTarget
from composite_scene import render_with_passes
from test_lens import _real_data


def _detect(image):
    import cv2

    board = cv2.aruco.CharucoBoard((5, 7), 0.04, 0.02, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(image)
    return board, corners.reshape(-1, 2), ids.ravel()


def _cg_square(bpy, scene, centre, side, name):
    s = side / 2
    x, y, z = centre
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x - s, y - s, z), (x + s, y - s, z), (x + s, y + s, z), (x - s, y + s, z)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new(name, mesh)
    mat = bpy.data.materials.get("CG White") or compat().new_material("CG White")
    nt = compat().node_tree(mat)
    nt.nodes.clear()
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(emit.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs[0])
    mesh.materials.append(mat)
    scene.collection.objects.link(ob)
    return ob


def test_cg_lands_on_real_board_corners_through_the_real_lens(bpy_clean, tmp_path):
    import cv2

    bpy = bpy_clean
    folder = _real_data() / "charuco_calibration"
    plate_dir = tmp_path / "plate"
    plate_dir.mkdir()
    for n, path in enumerate(sorted(folder.glob("img_*.jpg"))):
        shutil.copy(path, plate_dir / f"plate_{n + 1:04d}.jpg")
    scene = bpy.context.scene
    assert bpy.ops.platelight.setup_plate(filepath=str(plate_dir / "plate_0001.jpg"), fps=24) == {"FINISHED"}
    assert bpy.ops.platelight.track_markers(
        filepath=str(plate_dir), target="CHARUCO", dictionary="DICT_6X6_250", squares_x=5, squares_y=7,
        square_size=0.04, marker_size=0.02, calibration=str(folder / "tutorial_camera_charuco.yml")) == {"FINISHED"}
    from platelight.operators.lens import scene_lens

    assert scene_lens(scene) is not None                 # the tracker carried the lens in
    assert scene.active_clip.tracking.camera.distortion_model == "BROWN"

    photo = cv2.imread(str(plate_dir / "plate_0001.jpg"))
    board, corners, ids = _detect(photo)
    target = CharucoTarget("DICT_6X6_250", (5, 7), 0.04, 0.02)
    world = target.board_to_world(board.getChessboardCorners()[ids])
    chosen = [0, len(ids) // 3, 2 * len(ids) // 3, len(ids) - 1]   # spread over the board
    for k in chosen:
        _cg_square(bpy, scene, world[k] + np.array([0, 0, 0.0005]), 0.006, f"Dot {ids[k]}")
    assert bpy.ops.platelight.setup_composite(samples=8) == {"FINISHED"}
    scene.frame_set(1)
    out, passes = render_with_passes(bpy, scene, tmp_path)
    alpha = passes["CG"][..., 3]
    count, labels = cv2.connectedComponents((alpha > 0.05).astype(np.uint8))
    jj, ii = np.mgrid[0:alpha.shape[0], 0:alpha.shape[1]]
    blobs = []
    for label in range(1, count):
        w = alpha * (labels == label)
        if w.sum() > 4:
            blobs.append(np.array([(w * ii).sum(), (w * jj).sum()]) / w.sum())
    assert len(blobs) == len(chosen)
    errors = [min(np.linalg.norm(b - corners[k]) for b in blobs) for k in chosen]
    print("CG squares vs OpenCV's detected corners (px):", np.round(errors, 3))
    assert max(errors) < 1.0
