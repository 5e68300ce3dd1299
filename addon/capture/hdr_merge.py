"""Exposure brackets -> linear HDR radiance: Debevec & Malik response recovery and merge.

The response comes from OpenCV's ``CalibrateDebevec`` (g(128) = 0, i.e. the pixel value 128
maps to radiance x time = 1). The merge is done here in numpy rather than by ``MergeDebevec``
so that pixels clipped in *every* bracket are known and handled instead of silently coming out
far too dark (a sun in the sky): they are reported, set to their lower bound (the radiance that
just saturates the shortest exposure) and can be repaired with a grey card (``repair_clipped``).
"""
from __future__ import annotations

import dataclasses
import os
import struct

import numpy as np

from ..errors import PlateLightError
from ..imaging import srgb_to_linear
from ..wording import Sentence

SATURATED = 250      # 8-bit value from which a pixel counts as clipped
DARK = 5             # and below which as lost in the noise floor


# ------------------------------------------------------------------------------ EXIF
def exif_exposure_time(path: str | os.PathLike) -> float | None:
    """ExposureTime (seconds) from a JPEG's Exif block or a TIFF's IFDs, or None.

    A small TIFF/Exif reader: follows IFD0 -> Exif IFD (tag 0x8769) -> tag 0x829A (RATIONAL)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(1 << 20)
    except OSError:
        return None
    tiff = None
    if data[:2] == b"\xff\xd8":                          # JPEG: walk the segments to APP1 "Exif"
        i = 2
        while i + 4 <= len(data) and data[i] == 0xFF:
            marker = data[i + 1]
            length = struct.unpack(">H", data[i + 2:i + 4])[0]
            if marker == 0xE1 and data[i + 4:i + 10] == b"Exif\x00\x00":
                tiff = data[i + 10:i + 2 + length]
                break
            if marker in (0xDA, 0xD9):
                break
            i += 2 + length
    elif data[:4] in (b"II*\x00", b"MM\x00*"):
        tiff = data
    if not tiff or len(tiff) < 8:
        return None
    try:
        return _tiff_exposure_time(tiff)
    except (struct.error, IndexError, ZeroDivisionError):
        return None


def _tiff_exposure_time(tiff: bytes) -> float | None:
    end = "<" if tiff[:2] == b"II" else ">"

    def entries(offset):
        count = struct.unpack(end + "H", tiff[offset:offset + 2])[0]
        for k in range(count):
            e = offset + 2 + 12 * k
            tag, typ, n = struct.unpack(end + "HHI", tiff[e:e + 8])
            yield tag, typ, n, e + 8

    ifd0 = struct.unpack(end + "I", tiff[4:8])[0]
    for tag, typ, _, vpos in entries(ifd0):
        if tag == 0x829A and typ == 5:                   # ExposureTime directly in IFD0 (TIFF)
            return _rational(tiff, end, vpos)
        if tag == 0x8769:                                # pointer to the Exif IFD
            exif = struct.unpack(end + "I", tiff[vpos:vpos + 4])[0]
            for tag2, typ2, _, vpos2 in entries(exif):
                if tag2 == 0x829A and typ2 == 5:
                    return _rational(tiff, end, vpos2)
    return None


def _rational(tiff, end, vpos) -> float | None:
    off = struct.unpack(end + "I", tiff[vpos:vpos + 4])[0]
    num, den = struct.unpack(end + "II", tiff[off:off + 8])
    return num / den if den and num else None


# --------------------------------------------------------------------------- brackets
def read_brackets(paths, exposures=None) -> tuple[list[np.ndarray], np.ndarray]:
    """Read 8-bit brackets (BGR, as OpenCV reads them) and their exposure times, sorted from
    the shortest exposure. ``exposures`` overrides EXIF."""
    import cv2

    paths = [os.fspath(p) for p in paths]
    if len(paths) < 2:
        raise PlateLightError("A probe needs at least two differently exposed brackets; got one image.")
    images = []
    for p in paths:
        img = read_photo(p)
        if img.dtype == np.uint16:
            img = (img >> 8).astype(np.uint8)
        elif img.dtype != np.uint8:
            raise PlateLightError(f"Brackets must be 8- or 16-bit images; {p} is {img.dtype} (an HDR "
                                  f"file is a probe photo on its own: give it alone).")
        images.append(img)
    sizes = {im.shape[:2] for im in images}
    if len(sizes) != 1:
        desc = ", ".join(f"{im.shape[1]}x{im.shape[0]}" for im in images)
        raise PlateLightError(f"The brackets have different sizes ({desc}); they must be shots of one framing.")
    if exposures is None:
        times = [exif_exposure_time(p) for p in paths]
        missing = [os.path.basename(p) for p, t in zip(paths, times) if t is None]
        if missing:
            raise PlateLightError(
                f"No EXIF exposure time in {', '.join(missing)}; give them with {{exposures}}.",
                exposures="the exposure times (seconds, one per bracket)")
    else:
        times = [float(t) for t in exposures]
        if len(times) != len(paths):
            raise PlateLightError(f"{len(times)} exposure times were given for {len(paths)} brackets.")
    times = np.asarray(times, dtype=np.float64)
    if not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise PlateLightError("Exposure times must be positive numbers of seconds.")
    if len(set(np.round(np.log2(times), 3))) < 2:
        raise PlateLightError("All brackets have the same exposure time; an HDR merge needs different ones.")
    order = np.argsort(times)
    return [images[i] for i in order], times[order]


def read_photo(path: str) -> np.ndarray:
    """A photo as OpenCV reads it (BGR, 8/16-bit, or float32 for .hdr/.exr), 3 channels."""
    import cv2

    if not os.path.isfile(path):
        raise PlateLightError(f"Bracket not found: {path}")
    if path.lower().endswith((".hdr", ".pic", ".rgbe", ".exr")):
        from ..hdr_io import read_probe

        return np.ascontiguousarray(read_probe(path)[..., ::-1])
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise PlateLightError(f"Cannot read the bracket (not an image file, or damaged): {path}")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.shape[2] == 4:
        img = img[..., :3]
    return np.ascontiguousarray(img)


def srgb_response() -> np.ndarray:
    """The sRGB decoding curve as an inverse response (256, 3), value 128 -> 1 like Debevec's."""
    lin = srgb_to_linear(np.arange(256) / 255.0)
    return np.repeat((lin / lin[128])[:, None], 3, axis=1)


def single_photo(path: str, exposure: float | None = None) -> tuple[np.ndarray, "MergeResult", float | None]:
    """One photo -> (the photo as read, linear radiance, exposure time). An 8/16-bit photo is
    decoded with the sRGB curve (value 128 -> 1, like a merge, then / exposure time when known):
    an LDR probe whose highlights are clipped at the photo's white. A float photo (.hdr/.exr) is
    already radiance."""
    import cv2

    img = read_photo(path)
    t = float(exposure) if exposure is not None else exif_exposure_time(path)
    if t is not None and not (np.isfinite(t) and t > 0):
        raise PlateLightError("Exposure times must be positive numbers of seconds.")
    resp = srgb_response()
    if np.issubdtype(img.dtype, np.floating):
        rad = np.nan_to_num(np.maximum(img[..., ::-1], 0), nan=0.0, posinf=0.0).astype(np.float32)
        return img, MergeResult(rad, np.zeros(rad.shape[:2], bool), resp, []), t
    if img.dtype == np.uint16:
        lin = srgb_to_linear(img / np.float32(65535.0)).astype(np.float32)
        rad = lin / np.float32(srgb_to_linear(128 / 255.0))
        clipped_ch = img >= int(SATURATED / 255.0 * 65535)
    elif img.dtype == np.uint8:
        rad = cv2.LUT(img, np.ascontiguousarray(resp[None, :, :].astype(np.float32)))
        clipped_ch = img >= SATURATED
    else:
        raise PlateLightError(f"Photos must be 8- or 16-bit images or HDR files; {path} is {img.dtype}.")
    rad = rad[..., ::-1] / np.float32(t if t else 1.0)
    clipped = np.any(clipped_ch, axis=-1)
    if np.all(clipped) or np.all(img <= (DARK if img.dtype == np.uint8 else DARK * 257)):
        raise PlateLightError("The photo is all white or all black; its exposure does not fit the scene.")
    n = int(clipped.sum())
    warnings = [Sentence(f"one photo gives a low-dynamic-range probe: {100.0 * n / clipped.size:.2f} % of its "
                         f"pixels are clipped at the photo's white, so the light of the sun and of lamps is only a "
                         f"lower bound; shoot exposure brackets (or give {{grey_card}}) for their true energy",
                         grey_card="a grey card's box")]
    if t is None:
        warnings.append("no exposure time in the photo's EXIF: the probe's brightness is relative (value 128 -> 1)")
    return img, MergeResult(np.ascontiguousarray(rad, dtype=np.float32), clipped, resp, warnings), t


def recover_response(images, times, samples: int = 200, smoothness: float = 10.0,
                     shared: bool = True) -> np.ndarray:
    """Inverse camera response, shape (256, 3) (BGR like the images): linear exposure
    (radiance x time) for each 8-bit value, scaled so that value 128 -> 1 (Debevec & Malik 1997
    via OpenCV). Debevec fixes each channel's scale on its own, so per-channel noise becomes a
    colour cast; ``shared`` (default) averages the three log curves, as a camera's tone curve is
    the same for R, G and B (measured: 2.3 % -> 1.2 % median probe error after exposure)."""
    import cv2

    cal = cv2.createCalibrateDebevec(samples=samples, lambda_=smoothness, random=False)
    resp = cal.process(list(images), np.asarray(times, dtype=np.float32)).reshape(256, 3).astype(np.float64)
    if shared:
        resp = np.repeat(np.exp(np.log(np.maximum(resp, 1e-12)).mean(axis=1, keepdims=True)), 3, axis=1)
    return _extend_ends(resp)


def _extend_ends(resp: np.ndarray, low: int = 16, high: int = 235) -> np.ndarray:
    """Replace the ends of the curve, where the hat weights leave Debevec's solve nearly
    unconstrained (measured: +25 % at value 250), by a power law fitted just inside them; the
    clipping level's radiance (the lower bound of clipped light) is read there."""
    out = resp.copy()
    z = np.arange(256, dtype=np.float64)
    for lo, hi, ends in ((low, low + 32, z < low), (high - 40, high, z > high)):
        span = np.arange(lo, hi + 1)
        for c in range(resp.shape[1]):
            slope, icpt = np.polyfit(np.log(span), np.log(np.maximum(resp[span, c], 1e-12)), 1)
            out[ends, c] = np.exp(icpt + slope * np.log(np.maximum(z[ends], 0.5)))
    return out


def merge_weights(z: np.ndarray) -> np.ndarray:
    """Debevec's hat weight, zero at and beyond the clipping levels."""
    z = z.astype(np.float64)
    w = np.minimum(z - DARK, SATURATED - z)
    return np.clip(w, 0, None)


@dataclasses.dataclass
class MergeResult:
    radiance: np.ndarray          # (H, W, 3) float32, linear, RGB order
    clipped: np.ndarray           # (H, W) bool: clipped in every bracket
    response: np.ndarray          # (256, 3) RGB
    warnings: list[str]


def merge(images, times, response: np.ndarray | None = None, shared_response: bool = True) -> MergeResult:
    """Merge 8-bit BGR brackets (sorted shortest first) into linear RGB radiance.

    Weighted mean of log radiance (Debevec & Malik's Eq 6) through 256-entry lookup tables,
    one bracket at a time in float32 (5 brackets of 4000x3000 stay under 1 GiB)."""
    times = np.asarray(times, dtype=np.float64)
    if response is None:
        response = recover_response(images, times, shared=shared_response)
    resp_bgr = np.asarray(response, dtype=np.float64)
    if np.all(images[-1] >= SATURATED) or np.all(images[0] <= DARK):
        raise PlateLightError("The brackets are all white or all black; the exposures do not fit the scene.")
    weight_lut = merge_weights(np.arange(256)).astype(np.float32)
    log_lut = np.log(np.maximum(resp_bgr, 1e-12)).astype(np.float32)          # (256, 3)
    shape = images[0].shape
    num = np.zeros(shape, np.float32)
    den = np.zeros(shape, np.float32)
    import cv2

    weight_table = np.ascontiguousarray(np.repeat(weight_lut[None, :, None], 3, axis=2))
    for img, t in zip(images, times):
        # one table lookup per pixel (cv2.LUT, 10x numpy's fancy indexing): the weighted log
        # radiance of each 8-bit value is tabulated per bracket
        weighted = (weight_lut[:, None] * (log_lut - np.float32(np.log(t))))[None].astype(np.float32)
        num += cv2.LUT(img, np.ascontiguousarray(weighted))
        den += cv2.LUT(img, weight_table)
    # Clipped in every bracket: the shortest exposure saturates, so the radiance is at least
    # what saturates it; dark in every bracket: at most what the longest one records.
    clipped_ch = (den == 0) & (images[0] >= SATURATED)
    dark_ch = (den == 0) & ~clipped_ch
    log_rad = np.divide(num, np.maximum(den, np.float32(1e-6)))
    if clipped_ch.any():
        sat = (log_lut[SATURATED] - np.log(times[0])).astype(np.float32)
        log_rad = np.where(clipped_ch, sat, log_rad)
    if dark_ch.any():
        floor = cv2.LUT(images[-1], np.ascontiguousarray((log_lut - np.float32(np.log(times[-1])))[None]))
        log_rad = np.where(dark_ch, floor, log_rad)
    radiance = np.exp(log_rad[..., ::-1])
    clipped = np.any(clipped_ch, axis=-1)
    warnings = []
    n = int(clipped.sum())
    if n:
        warnings.append(
            f"{n} pixels ({100.0 * n / clipped.size:.3f} %) are clipped in every bracket (e.g. the sun): "
            f"their radiance is only a lower bound; add a shorter exposure or repair them with a grey card")
    return MergeResult(np.ascontiguousarray(radiance, dtype=np.float32), clipped,
                       resp_bgr[:, ::-1].copy(), warnings)


def clipped_region_summary(clipped_probe: np.ndarray) -> dict:
    """Solid angle (sr) and mean direction of the clipped texels of a lat-long mask."""
    from ..ibl.equirect import texel_directions, texel_solid_angles

    h, w = clipped_probe.shape
    sa = texel_solid_angles(h, w)
    if not clipped_probe.any():
        return {"solid_angle_sr": 0.0, "direction": None}
    d = (texel_directions(h, w)[clipped_probe] * sa[clipped_probe][:, None]).sum(0)
    return {"solid_angle_sr": float(sa[clipped_probe].sum()),
            "direction": (d / np.linalg.norm(d)).tolist()}


def repair_clipped(probe: np.ndarray, clipped: np.ndarray, card_radiance, card_albedo: float,
                   card_normal) -> tuple[np.ndarray, float]:
    """Raise the clipped texels of a lat-long ``probe`` so that it lights a Lambertian grey card
    as it was measured: a card of ``card_albedo`` facing ``card_normal`` photographed in the same
    brackets shows radiance ``card_radiance`` = albedo/π · E(normal). The irradiance missing from
    the probe (measured E minus what the probe's unclipped part gives) is put into the clipped
    texels, in proportion to their lower-bound values. Returns (probe, scale of clipped texels)."""
    from ..ibl.equirect import texel_directions, texel_solid_angles

    probe = np.asarray(probe, dtype=np.float64)
    h, w = probe.shape[:2]
    if not clipped.any():
        return probe.astype(np.float32), 1.0
    n = np.asarray(card_normal, dtype=np.float64)
    n /= np.linalg.norm(n)
    cosine = np.clip(texel_directions(h, w) @ n, 0, None) * texel_solid_angles(h, w)
    measured = np.pi * np.asarray(card_radiance, dtype=np.float64) / card_albedo       # E per channel
    lit = np.einsum("hw,hwc->c", cosine * ~clipped, probe)
    clip_part = np.einsum("hw,hwc->c", cosine * clipped, probe)
    if np.any(clip_part <= 0):
        raise PlateLightError("The grey card does not face the clipped region (e.g. the sun); "
                              "it cannot measure its brightness.")
    scale = (measured - lit) / clip_part
    if np.any(scale < 1):
        raise PlateLightError("The grey card is darker than the probe's unclipped light alone predicts; "
                              "check its albedo, normal and the exposure times.")
    out = probe.copy()
    out[clipped] *= scale
    return out.astype(np.float32), float(np.mean(scale))
