"""What colour encoding a plate file says it has, read from its own header (bpy-free).

Blender's own guess is kept where it is right and corrected where it is not (measured with
Blender 5.2): 16-bit PNG and TIFF load as float images but are sRGB-encoded; float TIFFs load
as "sRGB" although float TIFFs are written scene-linear; an EXR with ACEScg (AP1) primaries in
its ``chromaticities`` attribute loads as "Linear Rec.709". DPX: Blender's reader already turns
printing-density (log) DPX into linear values, so log and linear DPX are both linear once read.

The answer is a name in Blender's OCIO config (``Image.colorspace_settings.name``) and the reason,
or ``None`` where the file says nothing that Blender does not already know (movies)."""
from __future__ import annotations

import dataclasses
import os
import struct

import numpy as np

LINEAR = "Linear Rec.709"
SRGB = "sRGB"

# EXR chromaticities (red xy, green xy, blue xy, white xy) -> Blender colour space.
_PRIMARIES = {
    "ACEScg": (0.713, 0.293, 0.165, 0.830, 0.128, 0.044, 0.32168, 0.33767),            # AP1
    "ACES2065-1": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168, 0.33767),        # AP0
    "Linear Rec.709": (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290),
    "Linear Rec.2020": (0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290),
    "Linear DCI-P3 D65": (0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.3127, 0.3290),
}
# DPX transfer characteristic (SMPTE 268M, byte 801) -> the colour space of what Blender reads.
_DPX_TRANSFER = {1: (LINEAR, "printing-density log DPX, linearised by Blender's reader"),
                 2: (LINEAR, "linear DPX"),
                 3: (LINEAR, "logarithmic DPX, linearised by Blender's reader"),
                 5: ("Rec.1886", "SMPTE 274M (Rec.709 video) DPX"),
                 6: ("Rec.1886", "Rec.709 video DPX")}


@dataclasses.dataclass(frozen=True)
class PlateEncoding:
    colorspace: str | None   # a Blender colour-space name, or None: keep Blender's own choice
    reason: str              # what in the file said so, for the report


def file_encoding(path: str | os.PathLike) -> PlateEncoding:
    """The colour encoding ``path``'s header declares (see the module's docstring)."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return PlateEncoding(None, "unreadable header")
    if head.startswith(b"\x89PNG\r\n\x1a\n"):
        return _png(head)
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        return _tiff(path, head[:2] == b"II")
    if head[:4] == b"\x76\x2f\x31\x01":
        return _exr(head)
    if head.startswith(b"\xff\xd8"):
        return PlateEncoding(SRGB, "JPEG, sRGB-encoded")
    if head[:4] in (b"SDPX", b"XPDS"):
        transfer = head[801] if len(head) > 801 else 0
        name, why = _DPX_TRANSFER.get(transfer, (None, f"DPX transfer code {transfer}, left to Blender"))
        return PlateEncoding(name, why)
    return PlateEncoding(None, "no colour information in the file")


def _png(data: bytes) -> PlateEncoding:
    bits = data[24]
    pos, gamma = 8, None
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"cICP" and len(body) >= 2:   # ITU-T H.273 transfer: 8 linear, 13 sRGB
            if body[1] == 8:
                return PlateEncoding(LINEAR, f"{bits}-bit PNG, cICP linear transfer")
            return PlateEncoding(SRGB, f"{bits}-bit PNG, cICP transfer {body[1]}")
        if kind == b"sRGB":
            return PlateEncoding(SRGB, f"{bits}-bit PNG, sRGB chunk")
        if kind == b"gAMA" and len(body) == 4:
            gamma = struct.unpack(">I", body)[0] / 100000.0
        if kind in (b"IDAT", b"IEND"):
            break
        pos += 12 + length
    if gamma is not None and abs(gamma - 1.0) < 1e-3:
        return PlateEncoding(LINEAR, f"{bits}-bit PNG, gAMA 1.0 (linear)")
    return PlateEncoding(SRGB, f"{bits}-bit PNG, sRGB-encoded (PNG's default)")


def _tiff(path: str, little: bool) -> PlateEncoding:
    """Float samples (SampleFormat 3) are scene-linear by convention; integer ones sRGB."""
    end = "<" if little else ">"
    try:
        with open(path, "rb") as fh:
            fh.seek(4)
            (ifd,) = struct.unpack(end + "I", fh.read(4))
            fh.seek(ifd)
            (count,) = struct.unpack(end + "H", fh.read(2))
            entries = [struct.unpack(end + "HHI4s", fh.read(12)) for _ in range(min(count, 4096))]
            tags = {}
            for tag, typ, n, value in entries:
                if typ == 3 and n >= 1:   # SHORTs: in the entry when they fit, else at an offset
                    if n > 2:
                        fh.seek(struct.unpack(end + "I", value)[0])
                        value = fh.read(2)
                    tags[tag] = struct.unpack(end + "H", value[:2])[0]
    except (OSError, struct.error):
        return PlateEncoding(None, "TIFF header unreadable")
    bits = tags.get(258, 8)
    if tags.get(339, 1) == 3:
        return PlateEncoding(LINEAR, f"{bits}-bit float TIFF, scene-linear")
    return PlateEncoding(SRGB, f"{bits}-bit TIFF, sRGB-encoded")


def _exr(data: bytes) -> PlateEncoding:
    """Scene-linear; the primaries from the ``chromaticities`` attribute when it is there."""
    pos = 8
    while pos < len(data) and data[pos] != 0:
        name_end = data.index(b"\x00", pos)
        type_end = data.index(b"\x00", name_end + 1)
        name, kind = data[pos:name_end], data[name_end + 1:type_end]
        (size,) = struct.unpack("<i", data[type_end + 1:type_end + 5])
        value = data[type_end + 5:type_end + 5 + size]
        if name == b"chromaticities" and kind == b"chromaticities" and size == 32:
            xy = np.array(struct.unpack("<8f", value))
            for space, ref in _PRIMARIES.items():
                if np.allclose(xy, ref, atol=2e-3):
                    return PlateEncoding(space, f"EXR, {space} primaries in its chromaticities")
            return PlateEncoding(None, "EXR with primaries Blender's config has no name for; "
                                       "set the plate's colour space")
        pos = type_end + 5 + size
    return PlateEncoding(LINEAR, "EXR, scene-linear Rec.709 (no chromaticities)")
