"""Probe files as Blender reads them for a world: OpenEXR (any channel layout, exr_io) and
Radiance RGBE ``.hdr`` (read here, without bpy or OpenCV).

Radiance files: a ``#?RADIANCE`` (or ``#?RGBE``) line, header lines up to an empty line
(``FORMAT=32-bit_rle_rgbe`` or ``..._xyze``; ``EXPOSURE``, ``GAMMA``, ``PRIMARIES``,
``PIXASPECT``, ``VIEW``, comments and unknown lines are kept as text), a resolution line in any of
the eight orientations (``-Y H +X W`` is the usual top-to-bottom, left-to-right one), then
scanlines either run-length encoded per channel (the "new" RLE every writer uses) or flat
4-byte pixels (with the old RLE's repeat markers). Pixels decode as ``m · 2^(e - 136)``, as
Blender 5.2's loader and OpenCV's do (measured: equal to the last bit; Ward's Radiance adds
half a mantissa step). ``EXPOSURE`` is not divided out, as Blender does not either: the world
renders the values as stored, and the maps must match the world.
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np

from .errors import PlateLightError

RADIANCE_MAGIC = b"#?"
# CIE XYZ -> linear Rec.709 (D65), for FORMAT=32-bit_rle_xyze files
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]], dtype=np.float32)


@dataclasses.dataclass
class RadianceHeader:
    format: str
    width: int
    height: int
    lines: list[str]                 # every header line, as written
    exposure: float = 1.0            # product of the EXPOSURE lines (informative)


def read_probe(path: str | os.PathLike) -> np.ndarray:
    """A lat-long probe (or any HDR image) as float32 RGB (H, W, 3), first row on top, from an
    OpenEXR or a Radiance .hdr file, told apart by their first bytes, not their names."""
    from .exr_io import EXR_MAGIC, read_exr

    from .fileio import read_magic

    path = os.fspath(path)
    magic = read_magic(path, "an image file")
    if magic == EXR_MAGIC:
        return read_exr(path)
    if magic[:2] == RADIANCE_MAGIC:
        return read_radiance(path)[0]
    raise PlateLightError(f"Not an OpenEXR or Radiance HDR file (wrong magic number): {path}")


def read_radiance(path: str | os.PathLike) -> tuple[np.ndarray, RadianceHeader]:
    """(float32 RGB (H, W, 3) with the first row on top, header) of a Radiance RGBE file."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise PlateLightError(f"Cannot read {path}: {exc.strerror}") from None
    header, pos = _parse_header(data, path)
    rgbe = _decode_pixels(data, pos, header.lines[-1], path)
    image = _rgbe_to_float(rgbe)
    if header.format == "32-bit_rle_xyze":
        image = np.einsum("ij,hwj->hwi", XYZ_TO_REC709, image).astype(np.float32)
    return _orient(image, header.lines[-1]), header


def _parse_header(data: bytes, path: str) -> tuple[RadianceHeader, int]:
    if not data.startswith(RADIANCE_MAGIC):
        raise PlateLightError(f"Not a Radiance HDR file (no #? line at the start): {path}")
    lines, pos = [], 0
    while True:
        end = data.find(b"\n", pos)
        if end < 0 or end - pos > 4096:
            raise PlateLightError(f"Radiance HDR header is truncated or damaged (no empty line ends it): {path}")
        line = data[pos:end].rstrip(b"\r").decode("latin-1")
        pos = end + 1
        if line.strip() == "" and lines:
            break
        lines.append(line)
    fmt, exposure = "32-bit_rle_rgbe", 1.0
    for line in lines[1:]:
        key, _, value = line.partition("=")
        key = key.strip().upper()
        if key == "FORMAT":
            fmt = value.strip()
        elif key == "EXPOSURE":
            try:
                exposure *= float(value)
            except ValueError:
                pass                      # an unreadable informative line does not spoil the pixels
    if fmt not in ("32-bit_rle_rgbe", "32-bit_rle_xyze"):
        raise PlateLightError(f"Radiance HDR pixel format '{fmt}' is not RGBE or XYZE: {path}")
    end = data.find(b"\n", pos)
    size = data[pos:end if end >= 0 else len(data)].decode("latin-1", "replace").split()
    if (len(size) != 4 or {size[0][1:], size[2][1:]} != {"X", "Y"} or size[0][0] not in "+-"
            or size[2][0] not in "+-" or not size[1].isdigit() or not size[3].isdigit()):
        raise PlateLightError(f"Radiance HDR resolution line is missing or damaged ('{' '.join(size)[:40]}'): {path}")
    dims = {size[0][1]: int(size[1]), size[2][1]: int(size[3])}
    width, height = dims["X"], dims["Y"]
    if width < 1 or height < 1:
        raise PlateLightError(f"Radiance HDR image is empty ({width}x{height}): {path}")
    lines.append(" ".join(size))
    return RadianceHeader(fmt, width, height, lines, exposure), end + 1


def _decode_pixels(data: bytes, pos: int, resolution: str, path: str) -> np.ndarray:
    """(scanlines, length, 4) uint8 in file order: the resolution line's first axis counts the
    scanlines, its second their length, whichever way the image is turned afterwards."""
    buf = np.frombuffer(data, dtype=np.uint8)
    res = resolution.split()
    n_lines, length = int(res[1]), int(res[3])
    out = np.empty((n_lines, length, 4), np.uint8)
    total = len(buf)
    for row in range(n_lines):
        if pos + 4 > total:
            raise PlateLightError(f"Radiance HDR file is truncated (scanline {row + 1} of {n_lines}): {path}")
        b0, b1, b2, b3 = (int(v) for v in buf[pos:pos + 4])
        if 8 <= length < 32768 and b0 == 2 and b1 == 2 and (b2 << 8 | b3) == length and not (b2 & 0x80):
            pos = _read_rle_scanline(buf, pos + 4, out[row], length, path)
        else:
            pos = _read_flat_scanline(buf, pos, out, row, length, path)
    return out


def _read_rle_scanline(buf: np.ndarray, pos: int, line: np.ndarray, length: int, path: str) -> int:
    """The new RLE: each of the 4 channels in turn, runs (count > 128: repeat the next byte
    count-128 times) and literal dumps (count <= 128 bytes follow)."""
    total = len(buf)
    for ch in range(4):
        x = 0
        while x < length:
            if pos >= total:
                raise PlateLightError(f"Radiance HDR file is truncated inside a scanline: {path}")
            count = int(buf[pos])
            pos += 1
            if count > 128:
                count -= 128
                if x + count > length or pos >= total:
                    raise PlateLightError(f"Radiance HDR scanline data is damaged (a run overflows the line): {path}")
                line[x:x + count, ch] = buf[pos]
                pos += 1
            else:
                if count == 0 or x + count > length or pos + count > total:
                    raise PlateLightError(f"Radiance HDR scanline data is damaged (bad literal count): {path}")
                line[x:x + count, ch] = buf[pos:pos + count]
                pos += count
            x += count
    return pos


def _read_flat_scanline(buf, pos, out, row, length, path) -> int:
    """Flat 4-byte pixels; the old RLE marks a repeat of the previous pixel as (1, 1, 1, n)
    (counts of successive markers combine by shifting 8 bits)."""
    need = 4 * length
    if pos + need <= len(buf):
        chunk = buf[pos:pos + need].reshape(length, 4)
        if not np.any((chunk[:, 0] == 1) & (chunk[:, 1] == 1) & (chunk[:, 2] == 1)):
            out[row] = chunk
            return pos + need
    x, shift = 0, 0
    while x < length:
        if pos + 4 > len(buf):
            raise PlateLightError(f"Radiance HDR file is truncated (scanline {row + 1}): {path}")
        px = buf[pos:pos + 4]
        pos += 4
        if px[0] == 1 and px[1] == 1 and px[2] == 1:
            count = int(px[3]) << shift
            prev = out[row, x - 1] if x > 0 else (out[row - 1, -1] if row > 0 else None)
            if prev is None or x + count > length:
                raise PlateLightError(f"Radiance HDR scanline data is damaged (a repeat with nothing before it): {path}")
            out[row, x:x + count] = prev
            x += count
            shift += 8
        else:
            out[row, x] = px
            x += 1
            shift = 0
    return pos


def _rgbe_to_float(rgbe: np.ndarray) -> np.ndarray:
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(np.float32(1.0), e - 136), 0).astype(np.float32)
    return (rgbe[..., :3].astype(np.float32) * scale[..., None]).astype(np.float32)


def _orient(image: np.ndarray, resolution: str) -> np.ndarray:
    """File order -> first row on top, first column on the left. ``image`` is (lines, length)
    in file order; ``-Y H +X W`` needs nothing."""
    a, _, b, _ = resolution.split()
    if a[1] == "X":                        # X-major: scanlines are columns
        image = image.transpose(1, 0, 2)
        a, b = b, a
    if a[0] == "+":                        # +Y: the first scanline is the bottom one
        image = image[::-1]
    if b[0] == "-":                        # -X: scanlines run right to left
        image = image[:, ::-1]
    return np.ascontiguousarray(image)


def write_radiance(path: str | os.PathLike, image: np.ndarray, header_lines=(), rle: bool = True) -> None:
    """A float RGB image as Radiance RGBE (``-Y H +X W``), for tests and tools; ``header_lines``
    go between the magic line and FORMAT. Not atomic: never used on a user's files."""
    img = np.maximum(np.nan_to_num(np.asarray(image, dtype=np.float64)[..., :3]), 0)
    h, w = img.shape[:2]
    peak = img.max(axis=-1)
    mant, exp = np.frexp(peak)
    rgbe = np.zeros((h, w, 4), np.uint8)
    ok = peak > 1e-32
    scale = np.where(ok, mant * 256.0 / np.where(ok, peak, 1), 0)
    rgbe[..., :3] = np.clip(np.floor(img * scale[..., None]), 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(ok, exp + 128, 0).astype(np.uint8)
    head = ["#?RADIANCE", *header_lines, "FORMAT=32-bit_rle_rgbe", "", f"-Y {h} +X {w}", ""]
    body = bytearray("\n".join(head).encode("latin-1"))
    for row in rgbe:
        if not rle or not 8 <= w < 32768:
            body += row.tobytes()
            continue
        body += bytes([2, 2, w >> 8, w & 0xFF])
        for ch in range(4):
            data = row[:, ch]
            x = 0
            while x < w:
                run = 1
                while x + run < w and run < 127 and data[x + run] == data[x]:
                    run += 1
                if run >= 4:
                    body += bytes([128 + run, int(data[x])])
                    x += run
                    continue
                start = x
                while x < w and x - start < 128:
                    if x + 3 < w and data[x] == data[x + 1] == data[x + 2] == data[x + 3]:
                        break
                    x += 1
                body += bytes([x - start]) + data[start:x].tobytes()
    with open(os.fspath(path), "wb") as fh:
        fh.write(bytes(body))
