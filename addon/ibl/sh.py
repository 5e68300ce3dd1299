"""Real spherical harmonics in the convention of Ramamoorthi & Hanrahan (design.md).

Orthonormal, no Condon–Shortley sign in the real form: ``Y1,-1 = 0.488603·y``, ``Y1,0 = 0.488603·z``,
``Y1,1 = 0.488603·x``; coefficient index ``l*l + l + m``. Associated Legendre functions come from
the normalised three-term recurrence (no factorials, stable to high degree).

Two projections of a lat-long probe:
- ``project_exact``: an FFT along each row plus Fejér's first quadrature rule across rows. The
  equirect row centres are exactly Fejér's nodes, so the projection of any band-limited
  environment sampled at the texel centres is exact (to round-off) for ``lmax < H`` and
  ``lmax < W/2``; for other maps it is the integral of the band-limited interpolant.
- ``project_paper``: the paper's Eq 8–9 — a jittered (stratified) k×k grid on the unit square,
  mapped by θ = 2·arccos√(1−x), φ = 2πy, every sample weighted 4π/n (n = k²).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .equirect import dir_to_uv, sample_bilinear

INV_SQRT_4PI = 0.28209479177387814
SQRT2 = np.sqrt(2.0)


def num_coefficients(lmax: int) -> int:
    return (lmax + 1) ** 2


def sh_index(l: int, m: int) -> int:
    return l * l + l + m


def legendre_normalized(lmax: int, x: np.ndarray) -> np.ndarray:
    """P̄_l^m(x) for 0 ≤ m ≤ l ≤ lmax, shape (len(x), lmax+1, lmax+1) indexed [.., l, m], where
    Y_l0 = P̄_l^0 and Y_l±m = √2·P̄_l^m·cos/sin(mφ). Entries with m > l are zero."""
    x = np.asarray(x, dtype=np.float64).ravel()
    s = np.sqrt(np.maximum(0.0, 1.0 - x * x))
    out = np.zeros((x.size, lmax + 1, lmax + 1))
    pmm = np.full(x.size, INV_SQRT_4PI)
    for m in range(lmax + 1):
        if m > 0:
            pmm = pmm * (np.sqrt((2.0 * m + 1.0) / (2.0 * m)) * s)
        out[:, m, m] = pmm
        if m + 1 <= lmax:
            out[:, m + 1, m] = np.sqrt(2.0 * m + 3.0) * x * pmm
        for l in range(m + 2, lmax + 1):
            a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            out[:, l, m] = a * (x * out[:, l - 1, m] - b * out[:, l - 2, m])
    return out


def sh_basis(lmax: int, dirs: np.ndarray) -> np.ndarray:
    """Y_lm at unit directions (N, 3): shape (N, (lmax+1)²), column index l*l + l + m."""
    dirs = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    p = legendre_normalized(lmax, dirs[:, 2])
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    ms = np.arange(1, lmax + 1)
    cos_m = np.cos(phi[:, None] * ms)
    sin_m = np.sin(phi[:, None] * ms)
    out = np.empty((dirs.shape[0], num_coefficients(lmax)))
    for l in range(lmax + 1):
        out[:, sh_index(l, 0)] = p[:, l, 0]
        for m in range(1, l + 1):
            out[:, sh_index(l, m)] = SQRT2 * p[:, l, m] * cos_m[:, m - 1]
            out[:, sh_index(l, -m)] = SQRT2 * p[:, l, m] * sin_m[:, m - 1]
    return out


@lru_cache(maxsize=16)
def fejer_weights(n: int) -> np.ndarray:
    """Fejér's first rule on the nodes x_i = cos((i + 0.5)π/n): ∫₋₁¹ f(x)dx ≈ Σ w_i f(x_i),
    exact for polynomials of degree < n; all weights are positive."""
    theta = (np.arange(n) + 0.5) * np.pi / n
    j = np.arange(1, n // 2 + 1)
    series = (np.cos(2.0 * np.outer(theta, j)) / (4.0 * j * j - 1.0)).sum(axis=1)
    w = (2.0 / n) * (1.0 - 2.0 * series)
    w.setflags(write=False)
    return w


@lru_cache(maxsize=16)
def _row_legendre(height: int, lmax: int) -> np.ndarray:
    """P̄ at the cosines of a lat-long map's row centres (top row first), cached, laid out
    [m, l, row] so that each order m is one contiguous matrix for the batched products below."""
    theta = (np.arange(height) + 0.5) * np.pi / height
    table = np.ascontiguousarray(legendre_normalized(lmax, np.cos(theta)).transpose(2, 1, 0))
    table.setflags(write=False)
    return table


def _row_fourier(image: np.ndarray, mmax: int) -> np.ndarray:
    """G[m, i, 2c + {0,1}] = Re/Im Σ_j L[i, j, c]·e^{i m φ_j} for m ≤ mmax, φ_j = atan2(y, x)
    of column j. Columns run towards decreasing φ: φ_j = π − 2π(j + 0.5)/W, hence the phase."""
    h, w, c = image.shape
    planes = np.ascontiguousarray(np.moveaxis(image, 2, 0), dtype=np.float64)   # (C, H, W)
    spectrum = np.fft.rfft(planes, axis=2)[:, :, : mmax + 1]                    # (C, H, M)
    m = np.arange(mmax + 1)
    spectrum = spectrum * np.exp(1j * np.pi * m * (1.0 - 1.0 / w))
    out = np.empty((mmax + 1, h, 2 * c))
    out[:, :, 0::2] = spectrum.real.transpose(2, 1, 0)
    out[:, :, 1::2] = spectrum.imag.transpose(2, 1, 0)
    return out


@lru_cache(maxsize=64)
def _lm_layout(lmax: int):
    """Index arrays mapping coefficient rows to the [m, l] grid: (l, m) of the cosine/m = 0 rows
    and of the sine rows (m > 0), with their coefficient indices."""
    ls, ms = np.tril_indices(lmax + 1)                 # all 0 ≤ m ≤ l
    pos = ls * ls + ls + ms
    sin_sel = ms > 0
    return ls, ms, pos, ls[sin_sel], ms[sin_sel], (ls * ls + ls - ms)[sin_sel]


def _pack(integrals: np.ndarray, lmax: int, channels: int) -> np.ndarray:
    """[m, l, 2c+re/im] integrals → coefficient rows l*l + l ± m."""
    ls, ms, pos, sl, sm, spos = _lm_layout(lmax)
    scale = np.where(ms > 0, SQRT2, 1.0)[:, None]
    coeffs = np.empty((num_coefficients(lmax), channels))
    coeffs[pos] = integrals[ms, ls, 0::2] * scale
    coeffs[spos] = SQRT2 * integrals[sm, sl, 1::2]
    return coeffs


def project_exact(image: np.ndarray, lmax: int) -> np.ndarray:
    """SH coefficients ((lmax+1)², C) of a lat-long image (H, 2H, C) by exact quadrature."""
    h, w, channels = image.shape
    if lmax >= h or 2 * lmax >= w:
        raise ValueError(f"lmax {lmax} too high for a {w}x{h} map (needs lmax < H and lmax < W/2)")
    g = _row_fourier(image, lmax)                                      # (M, H, 2C)
    g *= (fejer_weights(h) * (2.0 * np.pi / w))[None, :, None]
    integrals = np.matmul(_row_legendre(h, lmax), g)                   # (M, L, 2C)
    return _pack(integrals, lmax, channels)


def paper_directions(samples: int, seed: int | None = 0) -> np.ndarray:
    """The paper's stratified directions (Eq 9): a k×k jittered grid, k = round(√samples)."""
    k = max(1, int(round(np.sqrt(samples))))
    rng = np.random.default_rng(seed)
    a, b = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    x = (a.ravel() + rng.random(k * k)) / k
    y = (b.ravel() + rng.random(k * k)) / k
    theta = 2.0 * np.arccos(np.sqrt(1.0 - x))
    phi = 2.0 * np.pi * y
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def project_paper(image: np.ndarray, lmax: int, samples: int = 4096, seed: int | None = 0) -> np.ndarray:
    """The paper's Eq 8: Σ L(ω) y_lm(ω) 4π/n over stratified directions (bilinear lookups)."""
    dirs = paper_directions(samples, seed)
    coeffs = np.zeros((num_coefficients(lmax), image.shape[2]))
    for start in range(0, dirs.shape[0], 32768):          # bounded memory for large n
        chunk = dirs[start:start + 32768]
        u, v = dir_to_uv(chunk)
        coeffs += sh_basis(lmax, chunk).T @ sample_bilinear(image, u, v)
    return coeffs * (4.0 * np.pi / dirs.shape[0])


@lru_cache(maxsize=64)
def lobe_factors(exponent: float, lmax: int) -> np.ndarray:
    """λ_l of the normalised Phong lobe (s+1)/(2π)·max(0, t)^s: λ_l = (s+1)∫₀¹ t^s P_l(t) dt,
    so that convolving Y_lm gives λ_l·Y_lm (Funk–Hecke). s = 1 is the clamped cosine / π
    (Ramamoorthi–Hanrahan's A_l/π). Gauss–Legendre on [0, 1], exact for integer s."""
    n = int(max(32, (exponent + lmax) / 2 + 8))
    nodes, weights = np.polynomial.legendre.leggauss(n)
    t = 0.5 * (nodes + 1.0)
    return _legendre_moments(t, 0.5 * weights * t ** exponent * (exponent + 1.0), lmax)


@lru_cache(maxsize=64)
def ggx_lobe_factors(alpha: float, lmax: int, steps: int = 16384) -> np.ndarray:
    """λ_l of the lobe of directions a GGX surface (roughness² = ``alpha``) reflects a head-on
    view into, normalised (λ_0 = 1): weight D(h)·G1(l)/4 at the angle θ from the mirror direction,
    h halfway (θ/2), Smith's G1 for the outgoing direction (the view's is 1). Midpoint rule in θ
    on [0, π/2], fine enough for alpha down to 0.01 (the lobe's width is about alpha radians)."""
    theta = (np.arange(steps) + 0.5) * (0.5 * np.pi / steps)
    a2 = float(alpha) ** 2
    cos_h = np.cos(0.5 * theta)
    d = a2 / (np.pi * (cos_h * cos_h * (a2 - 1.0) + 1.0) ** 2)
    smith = (np.sqrt(1.0 + a2 * np.tan(theta) ** 2) - 1.0) / 2.0
    wt = d / (1.0 + smith) * np.sin(theta)
    return _legendre_moments(np.cos(theta), wt / wt.sum(), lmax)


def _legendre_moments(t: np.ndarray, weights: np.ndarray, lmax: int) -> np.ndarray:
    """Σ weights·P_l(t) for l = 0..lmax (Legendre recurrence), read-only: the factor functions
    cache them and their callers share the array."""
    p_prev, p = np.ones_like(t), t.copy()
    out = np.empty(lmax + 1)
    out[0] = weights.sum()
    if lmax >= 1:
        out[1] = (weights * p).sum()
    for l in range(2, lmax + 1):
        p_prev, p = p, ((2 * l - 1) * t * p - (l - 1) * p_prev) / l
        out[l] = (weights * p).sum()
    out.setflags(write=False)
    return out


def synthesize(coeffs: np.ndarray, height: int, factors: np.ndarray | None = None) -> np.ndarray:
    """Evaluate Σ λ_l c_lm Y_lm at the texel centres of a (height, 2·height) lat-long map."""
    lmax = int(round(np.sqrt(coeffs.shape[0]))) - 1
    width, channels = 2 * height, coeffs.shape[1]
    scaled = np.asarray(coeffs, dtype=np.float64)
    if factors is not None:
        per_row = np.repeat(np.asarray(factors[: lmax + 1], dtype=np.float64), 2 * np.arange(lmax + 1) + 1)
        scaled = scaled * per_row[:, None]
    # parts[m, l, 2c + {cos, sin}]: the coefficients that multiply P̄_l^m(x)·cos/sin(mφ)
    ls, ms, pos, sl, sm, spos = _lm_layout(lmax)
    parts = np.zeros((lmax + 1, lmax + 1, 2 * channels))
    parts[ms, ls, 0::2] = scaled[pos] * np.where(ms > 0, SQRT2, 1.0)[:, None]
    parts[sm, sl, 1::2] = SQRT2 * scaled[spos]
    rows = np.matmul(_row_legendre(height, lmax).transpose(0, 2, 1), parts)   # (M, h, 2C)
    phi = np.pi - 2.0 * np.pi * (np.arange(width) + 0.5) / width
    m = np.arange(lmax + 1)
    trig = np.empty((2 * (lmax + 1), width))                            # [cos m0.., sin m0..]
    trig[0::2] = np.cos(np.outer(m, phi))
    trig[1::2] = np.sin(np.outer(m, phi))
    # out[i, j, c] = Σ_m rows[m, i, 2c]·cos(mφ_j) + rows[m, i, 2c+1]·sin(mφ_j)
    stacked = rows.reshape(lmax + 1, height, channels, 2).transpose(1, 2, 0, 3)
    stacked = stacked.reshape(height * channels, 2 * (lmax + 1))
    return (stacked @ trig).reshape(height, channels, width).transpose(0, 2, 1)
