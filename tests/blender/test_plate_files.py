"""Plates as they come from cameras: each file type is read in the colour space its file declares
(or the one the user names), and the composite equals the plate, decoded independently here,
wherever the CG does not reach. Bad colour-space names get one sentence and the scene is kept."""
import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.compositing.plate_encoding import file_encoding
from platelight.addon.exr_io import write_exr
from composite_scene import H, W, add_camera, add_sphere, add_sun, grey_world, render_with_passes
from test_composite_inputs import scene_state

RNG = np.random.default_rng(12)
CODES16 = RNG.integers(0, 65536, (H, W, 3), dtype=np.uint16)
CODES8 = (CODES16 >> 8).astype(np.uint8)


def srgb_decode(v):
    """IEC 61966-2-1, written out here as the independent reference."""
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def primaries_to_xyz(xy):
    """RGB -> XYZ matrix of primaries + white ((rx, ry, gx, gy, bx, by, wx, wy))."""
    p = np.array([[x / y, 1.0, (1 - x - y) / y] for x, y in np.reshape(xy[:6], (3, 2))]).T
    wx, wy = xy[6:]
    white = np.array([wx / wy, 1.0, (1 - wx - wy) / wy])
    return p * np.linalg.solve(p, white)


def bradford(src_white_xy, dst_white_xy):
    m = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])
    to_xyz = lambda xy: np.array([xy[0] / xy[1], 1.0, (1 - xy[0] - xy[1]) / xy[1]])  # noqa: E731
    gain = (m @ to_xyz(dst_white_xy)) / (m @ to_xyz(src_white_xy))
    return np.linalg.inv(m) @ np.diag(gain) @ m


AP1 = (0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767)
REC709 = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def write_plate(kind, path):
    """Write the plate file of ``kind``; return the scene-linear Rec.709 values it stands for."""
    import cv2
    import OpenEXR

    bgr = lambda a: np.ascontiguousarray(a[..., ::-1])  # noqa: E731
    if kind == "png8":
        assert cv2.imwrite(str(path), bgr(CODES8))
        return srgb_decode(CODES8 / 255.0)
    if kind in ("png16", "tiff16"):
        assert cv2.imwrite(str(path), bgr(CODES16))
        return srgb_decode(CODES16 / 65535.0)
    linear = (CODES16 / 65535.0 * 2.0).astype(np.float32)   # scene-linear, above 1 too
    if kind == "tiff_float":
        assert cv2.imwrite(str(path), bgr(linear))
        return linear
    if kind == "exr":
        write_exr(path, linear)
        return linear
    if kind == "exr_acescg":
        channels = {n: np.ascontiguousarray(linear[..., i]) for i, n in enumerate("RGB")}
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                  "chromaticities": AP1}
        OpenEXR.File(header, channels).write(str(path))
        to709 = (np.linalg.inv(primaries_to_xyz(REC709)) @ bradford(AP1[6:], REC709[6:])
                 @ primaries_to_xyz(AP1))
        return linear @ to709.T
    raise ValueError(kind)


def srgb_encode(v):
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * np.maximum(v, 0) ** (1 / 2.4) - 0.055)


# kind: (file name, colour space it must get, tolerance). sRGB files are compared in their own
# code values (OCIO's sRGB curve differs from the exact formula by up to 2.4e-5 in linear: less
# than one 16-bit code); float files in scene-linear values.
CASES = {
    "png8": ("plate.png", "sRGB", ("codes", 255, 0.02)),
    "png16": ("plate.png", "sRGB", ("codes", 65535, 1.0)),
    "tiff16": ("plate.tif", "sRGB", ("codes", 65535, 1.0)),
    "tiff_float": ("plate.tif", "Linear Rec.709", ("linear", 1, 1e-6)),
    "exr": ("plate.exr", "Linear Rec.709", ("linear", 1, 1e-6)),
    # measured 5e-7 on 5.2 (its config: Bradford D60->D65); 5.5e-4 on 4.5, whose config's AP1
    # matrix differs slightly
    "exr_acescg": ("plate.exr", "ACEScg", ("linear", 1, 1e-3)),
}


def composite_scene(bpy):
    scene = bpy.context.scene
    add_camera(bpy, scene)
    add_sphere(bpy, scene, location=(1.2, 0.0, 0.5))   # the CG covers part of the frame
    add_sun(bpy, scene)
    grey_world(bpy, scene, 0.3)
    return scene


@pytest.mark.parametrize("kind", sorted(CASES))
def test_plate_passes_unchanged_outside_the_cg(bpy_clean, tmp_path, kind):
    bpy = bpy_clean
    name, space, tol = CASES[kind]
    expected = write_plate(kind, tmp_path / name)
    assert file_encoding(tmp_path / name).colorspace == space
    scene = composite_scene(bpy)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / name)) == {"FINISHED"}
    assert bpy.data.images["PlateLight Plate"].colorspace_settings.name == space
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    out, passes = render_with_passes(bpy, scene, tmp_path)
    outside = passes["CG"][..., 3] == 0
    assert 0.2 < outside.mean() < 0.99          # the CG is in view, and most of the plate is not
    domain, scale, tol = tol
    if domain == "codes":
        err = np.abs(srgb_encode(out[..., :3]) - srgb_encode(expected)) * scale
    else:
        err = np.abs(out[..., :3] - expected)
    assert err[outside].max() <= tol, (kind, float(err[outside].max()))


def test_16bit_png_keeps_its_srgb_colours(bpy_clean, tmp_path):
    """The reported bug: a 16-bit PNG loads as a float image and was tagged Linear."""
    bpy = bpy_clean
    write_plate("png16", tmp_path / "plate.png")
    composite_scene(bpy)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.png")) == {"FINISHED"}
    image = bpy.data.images["PlateLight Plate"]
    assert image.is_float and image.colorspace_settings.name == "sRGB"


def test_user_colour_space_wins_and_lists_come_from_blender(bpy_clean, tmp_path):
    bpy = bpy_clean
    from platelight.operators.plate_colour import colour_space_names

    names = colour_space_names()
    assert {"sRGB", "Linear Rec.709", "ACEScg"} <= set(names)
    write_plate("png16", tmp_path / "plate.png")
    scene = composite_scene(bpy)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.png"),
                                          colorspace="Linear Rec.709") == {"FINISHED"}
    assert bpy.data.images["PlateLight Plate"].colorspace_settings.name == "Linear Rec.709"
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    out, passes = render_with_passes(bpy, scene, tmp_path)
    outside = passes["CG"][..., 3] == 0
    np.testing.assert_allclose(out[..., :3][outside], (CODES16 / 65535.0)[outside], atol=2e-6)
    log_spaces = [n for n in names if "Log" in n]
    if log_spaces:   # a camera log the running Blender knows is accepted as it is named
        assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.png"),
                                              colorspace=log_spaces[0]) == {"FINISHED"}
        assert bpy.data.images["PlateLight Plate"].colorspace_settings.name == log_spaces[0]


def test_unknown_colour_space_is_one_sentence_and_keeps_the_scene(bpy_clean, tmp_path):
    bpy = bpy_clean
    write_plate("png16", tmp_path / "plate.png")
    composite_scene(bpy)
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match=r"has no colour space 'LogC9000'; pick one") as err:
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.png"), colorspace="LogC9000")
    assert str(err.value).count("\n") <= 1
    assert scene_state(bpy) == before


def test_16bit_tiff_sequence_with_a_missing_frame(bpy_clean, tmp_path):
    import cv2

    bpy = bpy_clean
    for n in (1, 2, 4):
        assert cv2.imwrite(str(tmp_path / f"shot.{n:04d}.tif"), CODES16)
    composite_scene(bpy)
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match=r"1 missing frame\(s\) \(3\)"):
        bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "shot.0001.tif"))
    assert scene_state(bpy) == before
    assert cv2.imwrite(str(tmp_path / "shot.0003.tif"), CODES16)
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "shot.0001.tif")) == {"FINISHED"}
    assert bpy.context.scene.frame_end == 4
    assert bpy.data.images["PlateLight Plate"].colorspace_settings.name == "sRGB"


def test_dpx_plates_take_blenders_linearised_values(bpy_clean, tmp_path):
    """DPX written by Blender (linear and printing-density log): the header's transfer code is
    read, and the composite equals the pixels Blender decodes from the file (no DPX decoder here
    to compare with independently)."""
    bpy = bpy_clean
    scene = composite_scene(bpy)
    source = bpy.data.images.new("source", W, H, float_buffer=True)
    linear = np.concatenate([CODES16 / 65535.0 * 0.9, np.ones((H, W, 1))], -1)[::-1]
    source.pixels.foreach_set(linear.astype(np.float32).ravel())
    settings = scene.render.image_settings
    for log in (False, True):
        settings.file_format, settings.color_depth = "DPX", "16"   # render() below sets EXR
        settings.use_cineon_log = log
        path = tmp_path / ("log.dpx" if log else "lin.dpx")
        source.save_render(str(path), scene=scene)
        assert file_encoding(path).colorspace == "Linear Rec.709"
        assert ("log" in file_encoding(path).reason) == log
        assert bpy.ops.platelight.setup_plate(filepath=str(path)) == {"FINISHED"}
        plate = bpy.data.images["PlateLight Plate"]
        decoded = np.array(plate.pixels[:], np.float32).reshape(H, W, 4)[::-1, :, :3]
        assert np.abs(decoded - linear[::-1, :, :3]).max() < 0.02    # 16-bit (log: 10-bit-ish) codes
        assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
        out, passes = render_with_passes(bpy, scene, tmp_path / path.stem)
        outside = passes["CG"][..., 3] == 0
        np.testing.assert_allclose(out[..., :3][outside], decoded[outside], atol=1e-6)
