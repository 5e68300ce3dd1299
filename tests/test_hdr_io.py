"""Probe files as Blender reads them for a world: Radiance .hdr (RLE and flat scanlines, unusual
header lines, every orientation, damaged files) against OpenCV's reader and the source pixels,
EXR of any channel layout, and a real .hdr probe through `maps`, lights and the probe CLI."""
from __future__ import annotations

import glob
import json
import os

import cv2
import numpy as np
import OpenEXR
import pytest

import support
from platelight.addon.errors import PlateLightError
from platelight.addon.exr_io import read_exr
from platelight.addon.hdr_io import read_probe, read_radiance, write_radiance

UNUSUAL = ["# written by a test, with a comment", "EXPOSURE=2.0", "EXPOSURE= 0.5", "GAMMA=2.2",
           "PRIMARIES=0.640 0.330 0.300 0.600 0.150 0.060 0.3127 0.3290", "PIXASPECT=1.0",
           "VIEW= -vta -vp 0 0 0 -vd 0 1 0", "SOFTWARE=PlateLight tests", "CAPDATE=2026:12:01 16:00:00",
           "some line no reader knows"]


def _bundled(name="sunset"):
    import importlib.util

    spec = importlib.util.find_spec("bpy")              # found, not imported (no Blender needed)
    roots = list(spec.submodule_search_locations or []) if spec else []
    paths = [p for root in roots for p in glob.glob(os.path.join(root, "*", "datafiles", "studiolights",
                                                                   "world", f"{name}.exr"))]
    if not paths:
        pytest.skip("bpy's bundled HDRIs are not installed")
    return read_exr(paths[0])


@pytest.fixture(scope="module")
def hdri():
    return _bundled()


def test_opencv_written_hdr_matches_opencv_reader(hdri, tmp_path):
    path = tmp_path / "cv.hdr"
    assert cv2.imwrite(str(path), np.ascontiguousarray(hdri[..., ::-1]))
    ours = read_probe(path)
    theirs = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., ::-1]
    assert ours.shape == hdri.shape and ours.dtype == np.float32
    np.testing.assert_array_equal(ours, theirs)                 # m 2^(e-136), like OpenCV
    rel = np.abs(ours - hdri) / np.maximum(hdri, 1e-3)
    assert np.median(rel) < 0.005 and np.percentile(rel, 99) < 0.02


@pytest.mark.parametrize("rle", [True, False], ids=["rle", "flat"])
def test_unusual_header_lines_and_flat_scanlines(hdri, tmp_path, rle):
    path = tmp_path / "odd.hdr"
    write_radiance(path, hdri, UNUSUAL, rle=rle)
    image, header = read_radiance(path)
    assert header.exposure == pytest.approx(1.0) and header.format == "32-bit_rle_rgbe"
    assert "GAMMA=2.2" in header.lines
    # EXPOSURE is not divided out (Blender does not either): the pixels as stored
    rel = np.abs(image - hdri) / np.maximum(hdri, 1e-3)
    assert np.median(rel) < 0.005
    theirs = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert theirs is not None, "OpenCV cannot read this file"
    np.testing.assert_array_equal(image, theirs[..., ::-1])


@pytest.mark.parametrize("resolution,turn", [
    ("+Y {h} +X {w}", lambda a: a[::-1]),
    ("-Y {h} -X {w}", lambda a: a[:, ::-1]),
    ("+X {w} -Y {h}", lambda a: a.transpose(1, 0, 2)),                # columns, left to right
    ("-X {w} +Y {h}", lambda a: a[::-1, ::-1].transpose(1, 0, 2)),    # right to left, bottom up
])
def test_orientations(tmp_path, resolution, turn):
    """A file stored in another orientation reads the same way up: the stored scanlines are
    the picture turned as its resolution line says."""
    rng = np.random.default_rng(0)
    picture = rng.uniform(0.01, 4.0, (6, 10, 3)).astype(np.float32)
    write_radiance(tmp_path / "base.hdr", picture, rle=False)
    base = read_probe(tmp_path / "base.hdr")
    data = (tmp_path / "base.hdr").read_bytes()
    head, _, _ = data.partition(b"-Y 6 +X 10\n")
    stored = turn(base.copy())                          # picture -> file order for that line
    rgbe = _to_rgbe(stored)
    line = resolution.format(h=6, w=10)
    (tmp_path / "turned.hdr").write_bytes(head + line.encode() + b"\n" + rgbe.tobytes())
    np.testing.assert_allclose(read_probe(tmp_path / "turned.hdr"), base, rtol=1e-6)


def _to_rgbe(image):
    peak = image.max(-1)
    mant, exp = np.frexp(peak)
    out = np.zeros(image.shape[:2] + (4,), np.uint8)
    scale = mant * 256.0 / peak
    out[..., :3] = np.floor(image * scale[..., None]).astype(np.uint8)
    out[..., 3] = exp + 128
    return out


def test_bad_hdr_files_answer_in_one_sentence(tmp_path, hdri):
    good = tmp_path / "good.hdr"
    write_radiance(good, hdri[:8, :16])
    data = good.read_bytes()
    cases = {
        "no_magic.hdr": (b"RADIANCE\n" + data[11:], "Not an OpenEXR or Radiance HDR file"),
        "truncated.hdr": (data[: len(data) - 40], "truncated"),
        "no_blank.hdr": (b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n" + b"X" * 5000, "header is truncated or damaged"),
        "bad_size.hdr": (data.replace(b"-Y 8 +X 16", b"-Y 8 +Z 16"), "resolution line is missing or damaged"),
        "bad_format.hdr": (data.replace(b"32-bit_rle_rgbe", b"16-bit_rle_lab"), "is not RGBE or XYZE"),
        "empty.hdr": (b"", "Not an OpenEXR or Radiance HDR file"),
    }
    for name, (content, message) in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(PlateLightError, match=message):
            read_probe(tmp_path / name)
    # the maps CLI says it in one line on stderr
    proc = support.run_cli("maps", tmp_path / "truncated.hdr", "--out", tmp_path / "o")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "truncated" in proc.stderr


def test_xyze_file_converted_to_rec709(tmp_path):
    white = np.ones((4, 8, 3), np.float32)
    xyz = white @ np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]).T
    write_radiance(tmp_path / "xyz.hdr", xyz, rle=False)
    data = (tmp_path / "xyz.hdr").read_bytes().replace(b"32-bit_rle_rgbe", b"32-bit_rle_xyze")
    (tmp_path / "xyz.hdr").write_bytes(data)
    np.testing.assert_allclose(read_probe(tmp_path / "xyz.hdr"), white, atol=0.02)


def test_exr_of_any_channel_layout(tmp_path):
    rng = np.random.default_rng(1)
    rgb = rng.uniform(0, 5, (8, 16, 3)).astype(np.float32)
    planes = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    layered = {f"ViewLayer.Combined.{c}": p for c, p in planes.items()}
    layered.update({f"ViewLayer.Depth.{c}": np.zeros_like(p) for c, p in planes.items()})
    OpenEXR.File({"type": OpenEXR.scanlineimage}, layered).write(str(tmp_path / "layers.exr"))
    np.testing.assert_array_equal(read_probe(tmp_path / "layers.exr"), rgb)
    named = {f"diffuse.{c}": p for c, p in planes.items()}
    OpenEXR.File({"type": OpenEXR.scanlineimage}, named).write(str(tmp_path / "named.exr"))
    np.testing.assert_array_equal(read_probe(tmp_path / "named.exr"), rgb)
    parts = [OpenEXR.Part({"type": OpenEXR.scanlineimage}, {"Z": planes["R"]}, name="depth"),
             OpenEXR.Part({"type": OpenEXR.scanlineimage}, dict(planes, A=planes["R"]), name="rgba")]
    OpenEXR.File(parts).write(str(tmp_path / "parts.exr"))
    np.testing.assert_array_equal(read_probe(tmp_path / "parts.exr"), rgb)
    half = {c: p.astype(np.float16) for c, p in planes.items()}
    OpenEXR.File({"type": OpenEXR.scanlineimage}, half).write(str(tmp_path / "half.exr"))
    np.testing.assert_allclose(read_probe(tmp_path / "half.exr"), rgb, rtol=1e-3)
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Z": planes["R"]}).write(str(tmp_path / "depth.exr"))
    with pytest.raises(PlateLightError, match="no R, G, B or Y channels"):
        read_probe(tmp_path / "depth.exr")
    # a one-value pass (Blender's Object Index: X alone) is read by its layer's name, broadcast
    index = dict(layered, **{"ViewLayer.IndexOB.X": planes["G"]})
    OpenEXR.File({"type": OpenEXR.scanlineimage}, index).write(str(tmp_path / "index.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "index.exr", layer="IndexOB"),
                                  np.repeat(rgb[..., 1:2], 3, axis=-1))
    np.testing.assert_array_equal(read_exr(tmp_path / "index.exr"), rgb)


def test_real_hdr_probe_through_maps_lights_and_probe(hdri, tmp_path):
    """A bundled HDRI written as Radiance by OpenCV goes through `maps` like its EXR; the lights
    found from it match; and one .hdr photo of a ball is an HDR probe for the probe CLI."""
    from platelight.addon.ibl.lights import probe_lights

    exr, hdr = tmp_path / "sunset.exr", tmp_path / "sunset.hdr"
    from platelight.addon.exr_io import write_exr
    write_exr(exr, hdri)
    cv2.imwrite(str(hdr), np.ascontiguousarray(hdri[..., ::-1]))
    for src in (exr, hdr):
        proc = support.run_cli("maps", src, "--out", tmp_path / src.suffix[1:], "--maps", "diffuse,specular")
        assert proc.returncode == 0, proc.stderr
    for name in ("diffuse", "specular"):
        a, b = read_exr(tmp_path / "exr" / f"{name}.exr"), read_exr(tmp_path / "hdr" / f"{name}.exr")
        assert np.median(np.abs(b / a - 1)) < 0.005
    sh_exr = np.array(json.loads((tmp_path / "exr" / "sh.json").read_text())["coefficients"])
    sh_hdr = np.array(json.loads((tmp_path / "hdr" / "sh.json").read_text())["coefficients"])
    assert np.abs(sh_hdr[:9] - sh_exr[:9]).max() < 0.01 * np.abs(sh_exr[0]).max()
    la, lb = probe_lights(read_probe(exr), 8), probe_lights(read_probe(hdr), 8)
    assert len(la) == len(lb)
    for x, y in zip(la, lb):
        assert np.dot(x.direction, y.direction) > 0.999 and y.strength == pytest.approx(x.strength, rel=0.01)
