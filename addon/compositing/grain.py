"""Grain matching: measure a plate's sensor/film grain and make more of it for the CG.

Model. The plate is a smooth image S plus grain n: zero-mean Gaussian, stationary in shape, with a
per-channel variance that grows with the signal (the Poisson-Gaussian sensor model: read noise
plus shot noise)

    var_c(L) = a_c + b_c · L            (L: the local level of channel c)

and spatially correlated like white noise blurred by a Gaussian of standard deviation ``size``
pixels (the grain's size; 0 = independent pixels). ``correlation`` is then the grain's lag-1
autocorrelation, computed exactly from that discrete kernel.

Estimator (``estimate_grain``):

1. high-pass residual ``r = I - SG(I)``, SG a separable quadratic Savitzky-Golay smoother (15 taps):
   it passes every locally quadratic signal unchanged, so smooth shading barely leaks into r
   (a Gaussian blur would leak the signal's curvature);
2. flat pixels only: per channel and level bin, the half with the smallest gradient of a
   Gaussian-smoothed plate (edges and texture are left out; what remains is caught by 3);
3. robust spreads: MAD of r, and MAD of r's horizontal and vertical pixel differences;
4. how much of the grain the residual keeps, and its lag-1 autocorrelation, are known exactly for
   every grain size from the impulse response of (blur by size, then the high-pass): the measured
   ratio MAD(diff)²/MAD(r)² = 2(1 - ρ_residual) gives the size (table inversion), then
   var(grain) = var(r) / kept(size);
5. per channel, the bins' variances are fitted by weighted least squares to a + b·L with a, b ≥ 0
   (weights from each bin's sampling error); the slope b is kept only when it is significant
   (3 sigma), else the grain is taken as the same at every level.

The reference level of each channel is the median flat level; ``sigma`` is the grain's standard
deviation there and ``response`` the part of its variance that is signal-dependent
(b·L/(a + b·L)), which is what the compositor group needs to scale the grain to the CG's level.

Synthesis (``make_grain``): white Gaussian noise from a (seed, frame)-seeded generator, blurred
by the same kernel, scaled by its exact (not measured) standard deviation, times ``sigma``.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import PlateLightError
from ..imaging import srgb_to_linear

MIN_SIDE = 16                   # smaller plates hold too few pixels for a grain estimate
MAX_SIDE = 32768                # grain images larger than this are a mistake
MAX_PIXELS = 8192 * 8192
MAX_VALUE = 1e30                # larger pixels are treated like Inf (float32 sums would overflow)
MAX_SIZE = 3.0                  # grain sizes (px) the estimator can tell apart
LEVEL_BINS = 8
MIN_BIN_PIXELS = 200
MAD_TO_SIGMA = 1.482602218505602
SMOOTHER_RADIUS = 7             # Savitzky-Golay window 2·7+1 = 15 taps
MASK_BLUR = 4.0                 # Gaussian (px) for the level and the flatness of the plate
# below 0.3 px the kernel is nearly a delta: such grain is white (size 0)
_SIZES = np.concatenate([[0.0], np.round(np.arange(0.3, MAX_SIZE + 1e-9, 0.05), 4)])


def savgol_quadratic(radius: int) -> np.ndarray:
    """Savitzky-Golay smoothing weights (quadratic fit, window 2·radius + 1)."""
    m = radius
    i = np.arange(-m, m + 1, dtype=np.float64)
    return (3 * (3 * m * m + 3 * m - 1) - 15 * i * i) / ((2 * m + 1) * (4 * m * m + 4 * m - 3))


SMOOTHER = savgol_quadratic(SMOOTHER_RADIUS)


@dataclasses.dataclass(frozen=True)
class GrainStats:
    """Measured grain. Arrays are per channel (R, G, B).

    sigma: standard deviation at ``level``; level: reference level (median of the flat pixels);
    response: fraction of the variance at ``level`` that grows with the signal (0: the same grain
    everywhere, 1: pure shot noise, sigma ∝ √level); floor, slope: var(L) = floor + slope·L;
    size: Gaussian std (px) of the grain's spatial kernel; correlation: the grain's lag-1
    autocorrelation; pixels: flat pixels the estimate used (per channel)."""

    sigma: np.ndarray
    level: np.ndarray
    response: np.ndarray
    floor: np.ndarray
    slope: np.ndarray
    size: float
    correlation: float
    pixels: int

    def sigma_at(self, level) -> np.ndarray:
        """Grain standard deviation per channel at ``level`` (scalar or per channel)."""
        level = np.maximum(np.asarray(level, np.float64), 0.0)
        return np.sqrt(np.maximum(self.floor + self.slope * level, 0.0))

    @classmethod
    def constant(cls, sigma, size=0.0, level=(1.0, 1.0, 1.0)) -> "GrainStats":
        """Grain of the given sigma everywhere (no signal dependence)."""
        sigma = _rgb(sigma, "sigma")
        size = _check_size(size)
        return cls(sigma=sigma, level=_rgb(level, "level"), response=np.zeros(3), floor=sigma ** 2,
                   slope=np.zeros(3), size=size, correlation=grain_correlation(size), pixels=0)


def _rgb(value, name):
    arr = np.broadcast_to(np.asarray(value, np.float64), (3,)).copy()
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise PlateLightError(f"Grain {name} must be finite and not negative, got {arr.tolist()}.")
    return arr


def _check_size(size):
    size = float(size)
    if not math.isfinite(size) or size < 0 or size > MAX_SIZE:
        raise PlateLightError(f"Grain size must be between 0 and {MAX_SIZE} pixels, got {size}.")
    return size


# ---------------------------------------------------------------- kernels


def gaussian_kernel(size: float) -> np.ndarray:
    """Unit-sum 1-D Gaussian of std ``size`` px (truncated at 4 std); [1] for size < 0.05."""
    if size < 0.05:
        return np.ones(1)
    radius = max(1, int(math.ceil(4.0 * size)))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / size) ** 2)
    return k / k.sum()


def grain_correlation(size: float) -> float:
    """Lag-1 autocorrelation of white noise blurred by ``gaussian_kernel(size)`` (either axis)."""
    k = gaussian_kernel(size)
    return float(np.dot(k[:-1], k[1:]) / np.dot(k, k)) if k.size > 1 else 0.0


def _separable(image, kernel, border):
    import cv2

    k = np.asarray(kernel, np.float32)
    return cv2.sepFilter2D(image, cv2.CV_32F, k, k, borderType=border)


def _highpass(image, border=None):
    """Residual I - SG(I) of a float32 (H, W) image."""
    import cv2

    border = cv2.BORDER_REFLECT_101 if border is None else border
    return image - _separable(image, SMOOTHER, border)


@dataclasses.dataclass(frozen=True)
class _Table:
    sizes: np.ndarray       # grain size (px)
    kept: np.ndarray        # var(residual) / var(grain)
    rho: np.ndarray         # lag-1 autocorrelation of the residual


_table_cache: list = []


def _residual_table() -> _Table:
    """Exact residual statistics for each grain size, from impulse responses."""
    import cv2

    if _table_cache:
        return _table_cache[0]
    kept, rho = [], []
    for size in _SIZES:
        k = gaussian_kernel(size)
        n = k.size + SMOOTHER.size + 4
        delta = np.zeros((n, n), np.float32)
        delta[n // 2, n // 2] = 1.0
        h = _separable(delta, k, cv2.BORDER_CONSTANT) / float(np.dot(k, k))  # unit-variance grain
        h = _highpass(h, cv2.BORDER_CONSTANT).astype(np.float64)
        energy = float((h * h).sum())
        kept.append(energy)
        rho.append(float((h[:, :-1] * h[:, 1:]).sum()) / energy)
    table = _Table(_SIZES, np.array(kept), np.array(rho))
    if np.any(np.diff(table.rho) <= 0):
        raise AssertionError("residual autocorrelation is not monotonic in the grain size")
    _table_cache.append(table)
    return table


# ---------------------------------------------------------------- estimation


def _check_plate(plate):
    plate = np.asarray(plate)
    if plate.ndim != 3 or plate.shape[2] < 3:
        raise PlateLightError(f"The plate must be an RGB image (H, W, 3), got shape {plate.shape}.")
    if not np.issubdtype(plate.dtype, np.number):
        raise PlateLightError(f"The plate must hold numbers, got {plate.dtype}.")
    h, w = plate.shape[:2]
    if min(h, w) < MIN_SIDE:
        raise PlateLightError(f"The plate is too small to measure grain ({w}×{h}; needs at least "
                              f"{MIN_SIDE}×{MIN_SIDE} pixels).")
    return plate[..., :3].astype(np.float32)


def _mad2(values):
    """Robust variance (MAD², scaled for a Gaussian)."""
    return (MAD_TO_SIGMA * float(np.median(np.abs(values - np.median(values))))) ** 2


def estimate_grain(plate: np.ndarray) -> GrainStats:
    """Measure the grain of ``plate`` (float, (H, W, 3+), linear). NaN/Inf pixels (and absurd
    values above MAX_VALUE) and their neighbourhoods are ignored; a plate without grain gives
    sigma 0. See the module docstring."""
    import cv2

    plate = _check_plate(plate)
    with np.errstate(invalid="ignore"):
        valid = np.all(np.abs(plate) <= MAX_VALUE, axis=2)      # False for NaN and ±Inf too
    if not valid.any():
        raise PlateLightError(f"The plate has no usable pixels (finite, |value| ≤ {MAX_VALUE:g}) to "
                              "measure grain on.")
    plate = np.where(valid[..., None], plate, 0.0).astype(np.float32)
    # a pixel's residual and smoothed level depend on its smoothing window and blur neighbourhood
    reach = max(SMOOTHER.size // 2, int(math.ceil(3 * MASK_BLUR))) + 1
    valid = cv2.erode(valid.astype(np.uint8), np.ones((2 * reach + 1,) * 2, np.uint8),
                      borderType=cv2.BORDER_CONSTANT, borderValue=1).astype(bool)
    valid[:reach] = valid[-reach:] = False
    valid[:, :reach] = valid[:, -reach:] = False
    if valid.sum() < MIN_BIN_PIXELS:
        raise PlateLightError("Too few finite pixels away from the plate's edges to measure grain "
                              f"({int(valid.sum())}; needs {MIN_BIN_PIXELS}).")
    table = _residual_table()

    per_channel = []   # (levels, variances of the residual, weights) per channel
    ratios, weights = [], []
    used = 0
    for c in range(3):
        channel = np.ascontiguousarray(plate[..., c])
        residual = _highpass(channel)
        smooth = cv2.GaussianBlur(channel, (0, 0), MASK_BLUR, borderType=cv2.BORDER_REFLECT_101)
        gy, gx = np.gradient(smooth)
        gradient = np.hypot(gx, gy)
        level = smooth[valid]
        edges = np.unique(np.quantile(level, np.linspace(0, 1, LEVEL_BINS + 1)))
        bins = np.clip(np.searchsorted(edges, smooth, side="right") - 1, 0, max(len(edges) - 2, 0))
        levels, variances, counts = [], [], []
        flat_all = np.zeros_like(valid)
        for b in range(max(len(edges) - 1, 1)):
            in_bin = valid & (bins == b)
            if in_bin.sum() < 2 * MIN_BIN_PIXELS:
                continue
            flat = in_bin & (gradient <= np.median(gradient[in_bin]))
            flat_all |= flat
            levels.append(float(np.median(smooth[flat])))
            variances.append(_mad2(residual[flat]))
            counts.append(int(flat.sum()))
            dx = flat[:, :-1] & flat[:, 1:]
            dy = flat[:-1, :] & flat[1:, :]
            diffs = np.concatenate([(residual[:, 1:] - residual[:, :-1])[dx],
                                    (residual[1:, :] - residual[:-1, :])[dy]])
            if variances[-1] > 0 and diffs.size >= MIN_BIN_PIXELS:
                ratios.append(_mad2(diffs) / variances[-1])
                weights.append(counts[-1])
        if not counts:   # almost all pixels the same level: one bin
            flat = valid & (gradient <= np.median(gradient[valid]))
            flat_all = flat
            levels, variances, counts = [float(np.median(smooth[flat]))], [_mad2(residual[flat])], [int(flat.sum())]
        used = max(used, int(flat_all.sum()))
        per_channel.append((np.array(levels), np.array(variances), np.array(counts, float)))

    if ratios:
        # ratio = 2 (1 - rho_residual); weighted median over channels and bins
        order = np.argsort(ratios)
        cum = np.cumsum(np.array(weights, float)[order])
        ratio = float(np.array(ratios)[order][np.searchsorted(cum, cum[-1] / 2)])
        rho = 1.0 - ratio / 2.0
        size = float(np.interp(rho, table.rho, table.sizes))   # clamps outside the table
    else:
        size = 0.0
    kept = float(np.interp(size, table.sizes, table.kept))
    rho_residual = float(np.interp(size, table.sizes, table.rho))

    floor, slope, ref = np.zeros(3), np.zeros(3), np.zeros(3)
    for c, (levels, variances, counts) in enumerate(per_channel):
        floor[c], slope[c] = _fit_variance(np.maximum(levels, 0.0), variances / kept, counts, rho_residual)
        ref[c] = max(float(np.median(levels)), 0.0)
    variance = floor + slope * ref
    sigma = np.sqrt(variance)
    response = np.divide(slope * ref, variance, out=np.zeros(3), where=variance > 0)
    if not np.any(sigma > 0):
        size = 0.0
    return GrainStats(sigma=sigma, level=ref, response=response, floor=floor, slope=slope,
                      size=size, correlation=grain_correlation(size), pixels=used)


def _fit_variance(levels, variances, counts, rho):
    """(a, b) ≥ 0 of var = a + b·L over the level bins, weighted by each bin's sampling error.

    A MAD variance from n independent Gaussian samples has relative variance ≈ 5.45/n; a
    residual with lag-1 correlation ρ has fewer independent samples, n·((1-|ρ|)/(1+|ρ|))² (2-D,
    AR(1)-like). The slope is kept only when it explains the bins better than a constant by
    χ² > 9 (3 sigma); otherwise noise in a few bins would become a signal dependence that is
    then extrapolated to the CG's level."""
    effective = counts * ((1 - abs(rho)) / (1 + abs(rho))) ** 2
    w = effective / (5.45 * np.maximum(variances, 1e-30) ** 2)

    def chi2(a, b):
        return float((w * (a + b * levels - variances) ** 2).sum())

    a0 = float((w * variances).sum() / w.sum())
    best = (a0, 0.0)
    if levels.size >= 2 and np.ptp(levels) > 0:
        design = np.stack([np.ones_like(levels), levels], axis=1) * np.sqrt(w)[:, None]
        a, b = np.linalg.lstsq(design, variances * np.sqrt(w), rcond=None)[0]
        if not (a >= 0 and b >= 0):  # the constrained optimum lies on the boundary a = 0
            a, b = 0.0, max(float((w * levels * variances).sum() / max((w * levels ** 2).sum(), 1e-300)), 0.0)
        if chi2(*best) - chi2(a, b) > 9.0:
            best = (float(a), float(b))
    return best


# ---------------------------------------------------------------- synthesis


def make_grain(stats: GrainStats, width: int, height: int, frame: int, seed: int = 0) -> np.ndarray:
    """Zero-mean Gaussian grain, float32 (height, width, 3): per-channel std ``stats.sigma``,
    spatial kernel of std ``stats.size`` px. The same (seed, frame) gives the same grain; other
    frames give independent grain."""
    import cv2

    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise PlateLightError(f"Grain image {name} must be a whole number, got {value!r}.")
        if not 1 <= value <= MAX_SIDE:
            raise PlateLightError(f"Grain image {name} must be between 1 and {MAX_SIDE}, got {value}.")
    if width * height > MAX_PIXELS:
        raise PlateLightError(f"Grain image of {width}×{height} pixels is too large (at most "
                              f"{MAX_PIXELS} pixels).")
    for name, value in (("frame", frame), ("seed", seed)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise PlateLightError(f"Grain {name} must be a whole number, got {value!r}.")
    sigma = _rgb(stats.sigma, "sigma")
    size = _check_size(stats.size)
    if not np.any(sigma > 0):
        return np.zeros((height, width, 3), np.float32)
    kernel = gaussian_kernel(size)
    pad = kernel.size // 2
    # SeedSequence entropy must be non-negative: fold negative frames and seeds into 64 bits
    entropy = [int(seed) & 0xFFFFFFFFFFFFFFFF, int(frame) & 0xFFFFFFFFFFFFFFFF, 0x6772616E]
    rng = np.random.default_rng(np.random.SeedSequence(entropy))
    out = np.empty((height, width, 3), np.float32)
    scale = 1.0 / float(np.dot(kernel, kernel))       # std of the blurred unit noise is Σk²
    for c in range(3):
        white = rng.standard_normal((height + 2 * pad, width + 2 * pad), dtype=np.float32)
        if pad:
            white = _separable(white, kernel, cv2.BORDER_REFLECT_101)[pad:-pad, pad:-pad]
        out[..., c] = white * np.float32(sigma[c] * scale)
    return out


def linear_plate(image: np.ndarray, srgb: bool) -> np.ndarray:
    """A decoded plate frame as float32 linear RGB: ``image`` in OpenCV's channel order (BGR or
    BGRA, or grey), 8/16-bit (÷ max) or float; ``srgb`` decodes the sRGB transfer curve (as
    Blender does for sRGB footage before compositing)."""
    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[2] not in (1, 3, 4):
        raise PlateLightError(f"The plate frame is not an image (shape {image.shape}).")
    rgb = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., 2::-1]
    if np.issubdtype(rgb.dtype, np.integer):
        rgb = rgb.astype(np.float32) / np.float32(np.iinfo(image.dtype).max)
    else:
        rgb = rgb.astype(np.float32)
    if srgb:
        rgb = srgb_to_linear(rgb)
    return np.ascontiguousarray(rgb, dtype=np.float32)
