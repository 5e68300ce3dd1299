"""The plate on the phantoms: a phantom's albedo is estimated from the plate (plate / the phantoms
rendered white), so shaded by the scene's lights it looks like the plate from the plate's camera
(through its calibrated lens too); a chrome CG sphere then reflects the real floor's colours where
geometry says; hand-made phantom materials stay an option and come back untouched."""
import json
import math

import numpy as np
import pytest

import support  # noqa: F401
from support import compat
from platelight.addon.compositing import lens
from platelight.addon.exr_io import read_exr, write_exr
from composite_scene import metal_material, render_with_passes

W, H = 160, 120


def _camera(bpy, scene):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -4.0, 3.0)
    cam.rotation_euler = (math.radians(55), 0.0, 0.0)
    return cam


def _floor(bpy, scene, size=400.0):
    s = size / 2
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new("Floor", mesh)
    scene.collection.objects.link(ob)
    ob.platelight.phantom = True
    return ob


def _smooth_plate(path):
    """A smooth colourful plate (bilinear lookups of it agree to ~1e-4)."""
    j, i = np.mgrid[0:H, 0:W] / np.array([H, W])[:, None, None]
    plate = np.stack([0.3 + 0.25 * np.sin(6 * i), 0.3 + 0.25 * np.cos(5 * j), 0.2 + 0.2 * i * j], -1)
    write_exr(path, plate.astype(np.float32))
    return plate.astype(np.float32)


def _sky(bpy, scene, value=1.0):
    world = compat().new_world("Sky")
    compat().node_tree(world).nodes["Background"].inputs[0].default_value = (value, value, value, 1.0)
    scene.world = world


def _probe_view(bpy, scene, path):
    """Render what a camera ray sees (as a probe's would), pixel centres only (a 0.01-px box
    filter), without the composite."""
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01
    scene.render.use_compositing = False
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def test_phantom_shows_the_plate_to_probes(bpy_clean, tmp_path):
    """Seen from the plate's camera under the scene's light, the phantom floor is the plate itself
    (its albedo times the light it gets: the plate divided and multiplied by the same shading)."""
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    _camera(bpy, scene)
    _sky(bpy, scene)
    floor = _floor(bpy, scene)
    plate = _smooth_plate(tmp_path / "plate.exr")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    scene.camera.data.shift_x, scene.camera.data.shift_y = 0.03, -0.02    # an off-centre lens
    assert apply_phantom_surfaces(scene, [floor]) == 1
    seen = _probe_view(bpy, scene, tmp_path / "seen.exr")
    err = (np.abs(seen - plate) / plate)[2:-2, 2:-2]      # the rim: the denoiser's edge effects
    # the worst pixel carries the white render's noise (4 samples + OIDN, operators/phantoms.py
    # ALBEDO_SAMPLES): measured 0.022 (0.015 at 16 samples), the median 0.0006 (0.0013)
    assert np.median(err) < 2e-3 and err.max() < 3e-2, (float(np.median(err)), float(err.max()))


def test_phantom_plate_goes_through_the_calibrated_lens(bpy_clean, tmp_path):
    """With a distorted calibration the render camera is the overscan pinhole: from it the
    phantom looks like the plate undistorted by lens.undistort_to_render."""
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    _camera(bpy, scene)
    _sky(bpy, scene)
    floor = _floor(bpy, scene)
    plate = _smooth_plate(tmp_path / "plate.exr")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    calib = dict(fx=150.0, fy=150.0, cx=81.0, cy=58.5, dist=[-0.28, 0.08, 0.001, -0.0015, 0.0])
    (tmp_path / "lens.json").write_text(json.dumps({"intrinsics": calib, "image_size": [W, H]}))
    assert bpy.ops.platelight.setup_lens(filepath=str(tmp_path / "lens.json")) == {"FINISHED"}
    assert apply_phantom_surfaces(scene, [floor]) == 1
    seen = _probe_view(bpy, scene, tmp_path / "seen.exr")
    frame = lens.render_frame(calib["fx"], calib["fy"], calib["cx"], calib["cy"], calib["dist"], W, H)
    expected = lens.undistort_to_render(plate, calib["fx"], calib["fy"], calib["cx"], calib["cy"],
                                        calib["dist"], frame)
    # where the lookup falls inside the plate (outside it the shader extends the edge, remap is 0)
    j, i = np.mgrid[0:H, 0:W].astype(np.float64)
    u, v = frame.render_to_ideal(i, j)
    xd, yd = lens.distort_normalized((u - calib["cx"]) / calib["fx"], (v - calib["cy"]) / calib["fy"], calib["dist"])
    px, py = calib["fx"] * xd + calib["cx"], calib["fy"] * yd + calib["cy"]
    # (and a pixel in from the plate's rim, where the map's pixels are part plate, part nothing)
    inside = (px >= 1) & (px <= W - 2) & (py >= 1) & (py <= H - 2)
    inside[:2], inside[-2:], inside[:, :2], inside[:, -2:] = False, False, False, False
    err = np.abs(seen - expected)[inside] / expected[inside]
    # measured: median 0.16 %, max 0.8 % (the white render's noise)
    assert inside.mean() > 0.75 and np.median(err) < 3e-3 and err.max() < 2e-2, (float(np.median(err)), float(err.max()))


def _ground(cam_matrix, cam_data, scene):
    """World floor point (z = 0) of each plate pixel's centre ray: an independent pinhole."""
    frame = [cam_matrix @ v for v in cam_data.view_frame(scene=scene)]
    tr, br, bl, tl = (np.array(v) for v in frame)
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    top = tl[None, :] + u[:, None] * (tr - tl)[None, :]
    bottom = bl[None, :] + u[:, None] * (br - bl)[None, :]
    pts = top[None] + v[:, None, None] * (bottom - top)[None]
    origin = np.array(cam_matrix.translation)
    rays = pts - origin
    return origin, rays, origin - origin[2] / rays[..., 2:3] * rays


RED = (-2.5, -0.2, -1.6, 1.6)    # the red patch of the real floor: x0, x1, y0, y1 (metres)
CENTRE, RADIUS = np.array([-0.2, 0.6, 0.55]), 0.5


def _red(points):
    x, y = points[..., 0], points[..., 1]
    return (x > RED[0]) & (x < RED[1]) & (y > RED[2]) & (y < RED[3])


@pytest.mark.parametrize("surface", ["PLATE", "MATERIAL"])
def test_chrome_sphere_reflects_the_real_floor(bpy_clean, tmp_path, surface):
    bpy = bpy_clean
    scene = bpy.context.scene
    cam = _camera(bpy, scene)
    floor = _floor(bpy, scene)
    grey = compat().new_material("Hand-made grey")
    floor.data.materials.append(grey)
    bpy.context.view_layer.update()
    scene.render.resolution_x, scene.render.resolution_y = W, H
    origin, rays, ground = _ground(cam.matrix_world, cam.data, scene)
    plate = np.where(_red(ground)[..., None], np.array([0.7, 0.05, 0.05]), np.array([0.3, 0.3, 0.3]))
    write_exr(tmp_path / "plate.exr", plate.astype(np.float32))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    _sky(bpy, scene, 1.0)     # the light the plate was shot under: floor albedo = plate
    bpy.ops.mesh.primitive_uv_sphere_add(radius=RADIUS, location=tuple(CENTRE), segments=64, ring_count=32)
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(metal_material("Chrome", (1, 1, 1), 0.0))
    scene.platelight.phantom_surface = surface
    assert bpy.ops.platelight.setup_composite(samples=16) == {"FINISHED"}
    out, passes = render_with_passes(bpy, scene, tmp_path)
    cg = passes["CG"]

    # where each sphere pixel's mirror reflection meets the floor (analytic)
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    oc = origin - CENTRE
    b = d @ oc
    disc = b * b - (oc @ oc - RADIUS ** 2)
    t = -b - np.sqrt(np.maximum(disc, 0))
    hit = origin + t[..., None] * d
    normal = (hit - CENTRE) / RADIUS
    refl = d - 2 * (d * normal).sum(-1, keepdims=True) * normal
    down = refl[..., 2] < -0.05
    floor_hit = hit - hit[..., 2:3] / refl[..., 2:3] * refl
    core = (disc > 0) & (cg[..., 3] > 0.999)
    import cv2

    core = cv2.erode(core.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & down
    red_seen = core & _red(floor_hit)
    grey_seen = core & ~_red(floor_hit)
    # away from the patch's edges (the reflection magnifies them)
    red_seen = cv2.erode(red_seen.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    grey_seen = cv2.erode(grey_seen.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert red_seen.sum() >= 15 and grey_seen.sum() >= 15
    redness = cg[..., 0] / np.maximum(cg[..., 1], 1e-4)
    if surface == "PLATE":
        assert floor.material_slots[0].link == "OBJECT"
        # the mirror shows the plate's own colours, darkened only where the sphere keeps sky
        # light off the floor (the real floor would be darker there too)
        red_px, grey_px = np.median(cg[..., :3][red_seen], 0), np.median(cg[..., :3][grey_seen], 0)
        # measured: (0.657, 0.047, 0.047) and 0.300
        assert red_px[0] / red_px[1] > 8 and 0.6 < red_px[0] / 0.7 < 1.05
        assert abs(grey_px[0] / grey_px[1] - 1) < 0.1 and 0.6 < grey_px[1] / 0.3 < 1.05
    else:                                                # the hand-made grey: no red anywhere
        assert floor.material_slots[0].link == "DATA" and floor.material_slots[0].material == grey
        assert np.median(redness[red_seen]) < 1.3      # the hand-made grey: no red anywhere
    # switching back gives the floor its own material again
    scene.platelight.phantom_surface = "MATERIAL"
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    assert floor.material_slots[0].link == "DATA" and floor.material_slots[0].material == grey
    assert floor.data.materials[0] == grey


def test_object_linked_materials_come_back(bpy_clean, tmp_path):
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    _camera(bpy, scene)
    floor = _floor(bpy, scene)
    _smooth_plate(tmp_path / "plate.exr")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    own = bpy.data.materials.new("Own")
    floor.data.materials.append(None)
    floor.material_slots[0].link = "OBJECT"
    floor.material_slots[0].material = own
    assert apply_phantom_surfaces(scene, [floor]) == 1
    assert floor.material_slots[0].material.name == "PlateLight Phantom Plate"
    floor.platelight.phantom_surface = "MATERIAL"      # the per-object override
    assert apply_phantom_surfaces(scene, [floor]) == 0
    assert floor.material_slots[0].link == "OBJECT" and floor.material_slots[0].material == own


def _box(bpy, scene, centre, size):
    bpy.ops.mesh.primitive_cube_add(size=size, location=centre)
    box = bpy.context.active_object
    box.platelight.phantom = True
    return box


def _crosses_box(points, eye, lo, hi):
    """Does the segment from each point to ``eye`` pass through the box [lo, hi] (slab test)?"""
    d = eye - points
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - points) / d, (hi - points) / d
    near = np.nanmax(np.minimum(t0, t1), axis=-1)
    far = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (near <= far) & (far > 0) & (near < 1)


def test_filmed_phantoms_show_the_plate_only_where_the_camera_filmed_them(bpy_clean, tmp_path):
    """Where a view layer asks for the filmed phantoms (the baked composite's CG layer), a phantom
    point the plate's camera saw emits the plate's pixel there; one it did not see (the floor
    behind a box) keeps its diffuse, path-traced surface. Seen from above, in the dark, with no
    bounces: the filmed floor is the plate, the floor the box hid from the camera is black."""
    from bpy_extras.object_utils import world_to_camera_view

    from platelight.addon import names
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    plate_camera = _camera(bpy, scene)
    _sky(bpy, scene)
    floor = _floor(bpy, scene)
    lo, hi = np.array([-0.3, 0.3, 0.0]), np.array([0.3, 0.9, 0.6])
    box = _box(bpy, scene, tuple((lo + hi) / 2), 0.6)
    plate = _smooth_plate(tmp_path / "plate.exr")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert apply_phantom_surfaces(scene, [floor, box]) == 2
    # from above, looking down on the box and the floor behind it
    above = bpy.data.objects.new("Above", bpy.data.cameras.new("Above"))
    scene.collection.objects.link(above)
    above.location = (0.0, 1.2, 5.0)
    scene.camera = above
    _sky(bpy, scene, 0.0)
    scene.cycles.max_bounces = 0
    layer = bpy.context.view_layer
    bpy.context.view_layer.update()
    ground, origin, rays = _ground_from(above, scene)
    eye = np.array(plate_camera.matrix_world.translation)
    margin = np.array([0.08, 0.08, 0.08])
    on_floor = ~_crosses_box(ground, origin, lo - margin, hi + margin)       # the camera above sees the floor
    hidden = on_floor & _crosses_box(ground, eye, lo + margin, hi - margin)
    filmed = on_floor & ~_crosses_box(ground, eye, lo - margin, hi + margin)
    assert hidden.sum() > 100 and filmed.sum() > 1000

    seen_off = _probe_view(bpy, scene, tmp_path / "off.exr")
    layer[names.FILMED_PHANTOMS_KEY] = 1.0
    seen = _probe_view(bpy, scene, tmp_path / "on.exr")
    # the switch off: the diffuse floor in the dark
    assert np.abs(seen_off[filmed]).max() < 1e-3
    # the floor the plate's camera did not see: still its diffuse surface, black here (the plate
    # is 0.05 or more everywhere; measured: median 0, 95th percentile 0.009 from the pixels at
    # the hidden region's rim, where some of the 16 samples fall on the filmed side)
    assert np.median(seen[hidden]) < 1e-3 and np.percentile(seen[hidden], 95) < 0.02, np.percentile(seen[hidden], 95)
    # the filmed floor: the plate's pixel where the plate's camera sees that point
    uv = np.array([world_to_camera_view(scene, plate_camera, _vector(p))[:2] for p in ground[filmed]])
    col = np.clip((uv[:, 0] * W).astype(int), 0, W - 1)
    row = np.clip(((1 - uv[:, 1]) * H).astype(int), 0, H - 1)
    err = np.abs(seen[filmed] - plate[row, col]).max(-1)
    # one pixel of the smooth plate varies by up to 0.01; measured median 0.0022, 95th 0.0045
    assert np.median(err) < 0.006 and np.percentile(err, 95) < 0.02, (np.median(err), np.percentile(err, 95))


def _vector(p):
    from mathutils import Vector

    return Vector(tuple(float(c) for c in p))


def _ground_from(cam, scene):
    origin, rays, ground = _ground(cam.matrix_world, cam.data, scene)
    return ground, origin, rays


def test_a_phantom_hidden_from_the_camera_keeps_its_own_albedo(bpy_clean, tmp_path):
    """The floor the plate's camera saw only through a red box is grey floor, not red: a phantom
    point hidden from the camera takes its own phantom's albedo (the median of what the camera saw
    of it), not the albedo of whatever hid it. Seen from above under a white sky, direct light
    only, the path-traced (unfilmed) surfaces: the hidden floor is as grey as the filmed floor."""
    from platelight.addon import names
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    plate_camera = _camera(bpy, scene)
    _sky(bpy, scene, 1.0)
    floor = _floor(bpy, scene)
    lo, hi = np.array([-0.3, 0.3, 0.0]), np.array([0.3, 0.9, 0.6])
    box = _box(bpy, scene, tuple((lo + hi) / 2), 0.6)
    bpy.context.view_layer.update()
    scene.render.resolution_x, scene.render.resolution_y = W, H
    # the plate: the red box where a pixel's ray passes through it, the grey floor elsewhere
    origin, _rays, ground = _ground(plate_camera.matrix_world, plate_camera.data, scene)
    through_box = _crosses_box(ground, origin, lo, hi)
    plate = np.where(through_box[..., None], np.array([0.6, 0.08, 0.08]), np.array([0.3, 0.3, 0.3]))
    write_exr(tmp_path / "plate.exr", plate.astype(np.float32))
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    assert apply_phantom_surfaces(scene, [floor, box]) == 2
    box_albedo, floor_albedo = np.array(box[names.HIDDEN_ALBEDO_KEY]), np.array(floor[names.HIDDEN_ALBEDO_KEY])
    assert box_albedo[0] / box_albedo[1] > 5 and box_albedo[3] == 1.0, box_albedo
    assert abs(floor_albedo[0] / floor_albedo[1] - 1) < 0.02 and 0.25 < floor_albedo[1] < 0.45, floor_albedo
    # the filmed radiance leaves out each phantom's silhouette (its pixels mix the box with the
    # floor): no filmed distance there, and the box's red not smoothed into the floor's grey
    import cv2

    radiance = read_exr(bpy.path.abspath(bpy.data.images[names.PHANTOM_RADIANCE_IMAGE].filepath), "RGBA")
    kernel = np.ones((3, 3), np.uint8)
    box_px = through_box.astype(np.uint8)
    rim = (cv2.dilate(box_px, kernel) != cv2.erode(box_px, kernel, borderValue=1))
    # (the render's samples fall anywhere in a pixel: its silhouette may sit a pixel off the
    # plate's, drawn through pixel centres)
    near_rim = cv2.dilate(rim.astype(np.uint8), kernel).astype(bool)
    assert (radiance[..., 3][rim] == 0).mean() > 0.9 and (radiance[..., 3][~near_rim] > 0).all()
    box_core = cv2.erode(box_px, kernel, iterations=2).astype(bool)
    floor_core = ~cv2.dilate(box_px, kernel, iterations=2).astype(bool)
    assert (radiance[..., 0][box_core] / radiance[..., 1][box_core]).min() > 7.0
    assert np.abs(radiance[..., 0][floor_core] / radiance[..., 1][floor_core] - 1).max() < 1e-3

    above = bpy.data.objects.new("Above", bpy.data.cameras.new("Above"))
    scene.collection.objects.link(above)
    above.location = (0.0, 1.2, 5.0)
    scene.camera = above
    scene.cycles.max_bounces = 0
    bpy.context.view_layer.update()
    ground, origin, _ = _ground_from(above, scene)
    eye = np.array(plate_camera.matrix_world.translation)
    margin = np.array([0.08, 0.08, 0.08])
    on_floor = ~_crosses_box(ground, origin, lo - margin, hi + margin)
    hidden = on_floor & _crosses_box(ground, eye, lo + margin, hi - margin)
    filmed = on_floor & ~_crosses_box(ground, eye, lo - margin, hi + margin)
    assert hidden.sum() > 100 and filmed.sum() > 1000
    seen = _probe_view(bpy, scene, tmp_path / "above.exr")
    redness = seen[..., 0] / np.maximum(seen[..., 1], 1e-4)
    # before: the hidden floor took the box's red from the pixel in front of it (R/G about 7)
    assert np.median(seen[hidden][:, 1]) > 0.05
    assert np.median(redness[hidden]) < 1.1 and np.median(redness[filmed]) < 1.1, \
        (np.median(redness[hidden]), np.median(redness[filmed]))
    # giving the phantoms their own materials back takes the property away too
    scene.platelight.phantom_surface = "MATERIAL"
    assert apply_phantom_surfaces(scene, [floor, box]) == 0
    assert names.HIDDEN_ALBEDO_KEY not in floor and names.HIDDEN_ALBEDO_KEY not in box


def test_a_new_plate_reaches_the_next_render_with_persistent_data(bpy_clean, tmp_path):
    """Set Up Composite turns persistent data on (a shot syncs its scene once). Setting the
    phantoms up again for another plate rewrites their maps under the same file names; the next
    render must show the new plate, not the images Cycles kept from the last one."""
    from platelight.addon import names
    from platelight.operators.phantoms import apply_phantom_surfaces

    bpy = bpy_clean
    scene = bpy.context.scene
    _camera(bpy, scene)
    _sky(bpy, scene, 1.0)
    floor = _floor(bpy, scene)
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.use_persistent_data = True
    bpy.context.view_layer[names.FILMED_PHANTOMS_KEY] = 1.0
    scene.cycles.max_bounces = 0
    seen = []
    for scale in (1.0, 0.5):
        path = tmp_path / f"plate_{scale}.exr"        # another footage file; the maps' names stay
        write_exr(path, _smooth_plate(path) * scale)
        assert bpy.ops.platelight.setup_plate(filepath=str(path)) == {"FINISHED"}
        assert apply_phantom_surfaces(scene, [floor]) == 1
        seen.append(_probe_view(bpy, scene, tmp_path / f"seen_{scale}.exr"))
    # the plate camera's own view of the filmed floor: the plate itself, then half of it
    inner = (slice(4, H - 4), slice(4, W - 4))
    ratio = np.median(seen[1][inner] / np.maximum(seen[0][inner], 1e-6))
    assert abs(ratio - 0.5) < 0.02, ratio


def test_filmed_radiance_takes_phantoms_the_frame_does_not_show(bpy_clean):
    """A phantom out of the frame (no pixel) or a sliver (no pixel inside its silhouette) leaves
    the radiance map as it is, filmed nowhere, instead of failing the set-up."""
    from platelight.operators.phantoms import _filmed_radiance

    pixels = np.full((40, 60, 3), 0.3, np.float32)
    distance = np.full((40, 60), 5.0, np.float32)
    whose = np.ones((40, 60), np.int64)
    whose[10:30, 20] = 3                     # a 1-px sliver; phantom 2 is out of the frame
    radiance = _filmed_radiance(pixels, distance, whose, 3)
    assert np.isfinite(radiance).all()
    assert (radiance[10:30, 20, 3] == 0).all()                          # the sliver: not filmed
    assert (radiance[:, 30:, 3] > 0).all() and np.allclose(radiance[:, 30:, :3], 0.3)
