"""Display helpers: the sRGB transfer curve both ways, HDR → 8-bit sRGB previews, labelled
contact sheets (OpenCV for PNG), and the PSNR that compares a render with its reference."""
from __future__ import annotations

import os

import numpy as np

LUMA = np.array([0.2126, 0.7152, 0.0722])


def auto_exposure(image: np.ndarray, key: float = 0.18) -> float:
    """Exposure that maps the log-average luminance to ``key`` (Reinhard et al. 2002)."""
    lum = np.asarray(image[..., :3], dtype=np.float64) @ LUMA
    lum = lum[np.isfinite(lum)]
    if lum.size == 0:
        return 1.0
    log_avg = float(np.exp(np.mean(np.log(1e-6 + np.maximum(lum, 0)))))
    return key / max(log_avg, 1e-6)


def reinhard(image: np.ndarray, exposure: float = 1.0, white: float | None = None) -> np.ndarray:
    """Reinhard's global operator on luminance, colour ratios kept; ``white`` burns out highlights."""
    rgb = np.maximum(np.nan_to_num(np.asarray(image[..., :3], dtype=np.float64)), 0) * exposure
    lum = rgb @ LUMA
    mapped = lum / (1.0 + lum) if white is None else lum * (1 + lum / white ** 2) / (1.0 + lum)
    scale = np.where(lum > 0, mapped / np.maximum(lum, 1e-12), 0.0)
    return np.clip(rgb * scale[..., None], 0, 1)


def psnr(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
         peak: float | None = None) -> float:
    """PSNR (dB) of ``image`` against ``reference`` over ``mask`` (default: every pixel), both
    clipped to 0..``peak`` (default: the reference's 99.5th percentile, so that a few sun pixels
    do not set the scale)."""
    image, reference = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    if peak is None:
        peak = float(np.percentile(reference, 99.5)) or 1.0
    error = (np.clip(image, 0, peak) - np.clip(reference, 0, peak)) ** 2
    mse = float(error[mask].mean() if mask is not None else error.mean())
    return float(10 * np.log10(peak ** 2 / max(mse, 1e-20)))


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """Decode the sRGB transfer curve (values in 0..1; the dtype of ``values`` is kept)."""
    return np.where(values <= 0.04045, values / 12.92, ((np.maximum(values, 0.04045) + 0.055) / 1.055) ** 2.4)


# 8-bit sRGB code -> linear light, scaled to 0..255 (float32): a lookup table for whole images
SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32) * 255.0


def linear_to_srgb8(rgb: np.ndarray) -> np.ndarray:
    rgb = np.clip(np.nan_to_num(rgb), 0, 1)
    srgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def preview(image: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """8-bit sRGB RGB preview of an HDR image."""
    exposure = auto_exposure(image) if exposure is None else exposure
    return linear_to_srgb8(reinhard(image, exposure))


def contact_sheet(tiles: list[tuple[str, np.ndarray]], tile_height: int = 192) -> np.ndarray:
    """Lay 8-bit RGB tiles side by side at one height (nearest-neighbour scaling keeps texels
    visible), each with its label. Returns an 8-bit RGB image."""
    import cv2

    row = []
    for label, tile in tiles:
        h, w = tile.shape[:2]
        width = max(1, round(w * tile_height / h))
        scaled = cv2.resize(tile, (width, tile_height), interpolation=cv2.INTER_NEAREST)
        band = np.full((24, width, 3), 32, np.uint8)
        cv2.putText(band, label, (4, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (240, 240, 240), 1, cv2.LINE_AA)
        row.append(np.vstack([band, scaled]))
        row.append(np.full((tile_height + 24, 4, 3), 255, np.uint8))
    return np.hstack(row[:-1])


def write_png(path: str | os.PathLike, rgb8: np.ndarray) -> None:
    """Write an 8-bit RGB image as PNG (atomically)."""
    import cv2

    from .errors import PlateLightError

    path = os.fspath(path)
    tmp = path + ".tmp.png"
    if not cv2.imwrite(tmp, np.ascontiguousarray(rgb8[..., ::-1])):
        raise PlateLightError(f"Cannot write PNG {path}.")
    os.replace(tmp, path)
