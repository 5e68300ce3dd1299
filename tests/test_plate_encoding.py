"""The plate's colour encoding read from file headers (no Blender): PNG chunks, TIFF sample
format, EXR chromaticities, DPX transfer codes, JPEG."""
import struct
import zlib

import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.compositing.plate_encoding import file_encoding
from platelight.addon.exr_io import write_exr


def _png_with_chunk(path, kind, body):
    import cv2

    assert cv2.imwrite(str(path), np.zeros((4, 4, 3), np.uint16))
    data = path.read_bytes()
    chunk = struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    ihdr_end = 8 + 8 + 13 + 4
    path.write_bytes(data[:ihdr_end] + chunk + data[ihdr_end:])


@pytest.mark.parametrize("kind, body, space", [
    (b"gAMA", struct.pack(">I", 100000), "Linear Rec.709"),
    (b"gAMA", struct.pack(">I", 45455), "sRGB"),
    (b"cICP", bytes([1, 8, 0, 1]), "Linear Rec.709"),
    (b"cICP", bytes([1, 13, 0, 1]), "sRGB"),
    (b"sRGB", bytes([0]), "sRGB"),
])
def test_png_chunks(tmp_path, kind, body, space):
    _png_with_chunk(tmp_path / "p.png", kind, body)
    assert file_encoding(tmp_path / "p.png").colorspace == space


def test_png_and_tiff_defaults(tmp_path):
    import cv2

    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((4, 4, 3), np.uint16))
    cv2.imwrite(str(tmp_path / "a.tif"), np.zeros((4, 4, 3), np.uint16))
    cv2.imwrite(str(tmp_path / "f.tif"), np.zeros((4, 4, 3), np.float32))
    cv2.imwrite(str(tmp_path / "g.tif"), np.zeros((4, 4), np.float32))
    cv2.imwrite(str(tmp_path / "a.jpg"), np.zeros((4, 4, 3), np.uint8))
    assert file_encoding(tmp_path / "a.png").colorspace == "sRGB"
    assert "16-bit PNG" in file_encoding(tmp_path / "a.png").reason
    assert file_encoding(tmp_path / "a.tif").colorspace == "sRGB"
    assert file_encoding(tmp_path / "f.tif").colorspace == "Linear Rec.709"
    assert file_encoding(tmp_path / "g.tif").colorspace == "Linear Rec.709"     # one sample: in the entry
    assert file_encoding(tmp_path / "a.jpg").colorspace == "sRGB"


def test_exr_chromaticities(tmp_path):
    import OpenEXR

    write_exr(tmp_path / "plain.exr", np.zeros((4, 4, 3), np.float32))
    assert file_encoding(tmp_path / "plain.exr").colorspace == "Linear Rec.709"
    cases = {"ACEScg": (0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767),
             "ACES2065-1": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168, 0.33767),
             "Linear Rec.2020": (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290),
             None: (0.6, 0.3, 0.3, 0.6, 0.1, 0.1, 0.33, 0.33)}
    for space, xy in cases.items():
        channels = {c: np.zeros((4, 4), np.float32) for c in "RGB"}
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "chromaticities": xy}
        OpenEXR.File(header, channels).write(str(tmp_path / "c.exr"))
        assert file_encoding(tmp_path / "c.exr").colorspace == space


@pytest.mark.parametrize("magic", [b"SDPX", b"XPDS"])
@pytest.mark.parametrize("transfer, space", [(1, "Linear Rec.709"), (2, "Linear Rec.709"), (3, "Linear Rec.709"),
                                             (6, "Rec.1886"), (9, None)])
def test_dpx_transfer(tmp_path, magic, transfer, space):
    header = bytearray(2048)
    header[:4] = magic
    header[801] = transfer
    (tmp_path / "f.dpx").write_bytes(bytes(header))
    assert file_encoding(tmp_path / "f.dpx").colorspace == space


def test_unknown_and_unreadable(tmp_path):
    (tmp_path / "x.bin").write_bytes(b"hello")
    assert file_encoding(tmp_path / "x.bin").colorspace is None
    assert file_encoding(tmp_path / "missing.png").colorspace is None
