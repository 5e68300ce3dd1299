"""Independent brute-force references for the engine's maps, written without the engine's code.

Directions and texel solid angles are derived here again from design.md's formulas; the
convolution is a direct sum over every source texel: value(n) = Σ L(ω)·k(n·ω)·ΔΩ(ω)."""
from __future__ import annotations

import numpy as np


def texel_grid(height: int):
    """Directions (H*W, 3) and exact solid angles (H*W,) of a (height, 2*height) lat-long map."""
    width = 2 * height
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    az = 2 * np.pi * (u - 0.5)                       # atan2(-y, x)
    el = np.pi * (v - 0.5)
    d = np.empty((height, width, 3))
    d[..., 0] = np.cos(el)[:, None] * np.cos(az)[None, :]
    d[..., 1] = -np.cos(el)[:, None] * np.sin(az)[None, :]
    d[..., 2] = np.sin(el)[:, None]
    top = np.pi / 2 - np.pi * np.arange(height) / height
    bottom = top - np.pi / height
    sa = (2 * np.pi / width) * (np.sin(top) - np.sin(bottom))
    return d.reshape(-1, 3), np.repeat(sa, width)


def phong_kernel(exponent: float):
    return lambda c: (exponent + 1) / (2 * np.pi) * np.maximum(c, 0.0) ** exponent


def ggx_kernel(roughness: float):
    """The directions a GGX surface (alpha = roughness²) seen head-on reflects into, as a function
    of their angle θ from the mirror direction: D at the half vector (θ/2) times Smith's G1 of the
    outgoing direction, normalised to integrate to 1 over the sphere."""
    a2 = roughness ** 4

    def weight(c):
        c = np.clip(c, -1.0, 1.0)
        cos_h2 = (1.0 + c) / 2.0                      # cos²(θ/2)
        d = a2 / (np.pi * (cos_h2 * (a2 - 1.0) + 1.0) ** 2)
        tan2 = (1.0 - c * c) / np.maximum(c * c, 1e-300)
        g1 = 2.0 / (1.0 + np.sqrt(1.0 + a2 * tan2))
        return np.where(c > 0.0, d * g1, 0.0)

    theta = np.linspace(0.0, np.pi / 2, 400001)
    f = weight(np.cos(theta)) * np.sin(theta)
    norm = 2 * np.pi * np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(theta))     # trapezoids (numpy 1 and 2)
    return lambda c: weight(c) / norm


def convolve(env: np.ndarray, kernel, out_height: int, chunk: int = 64) -> np.ndarray:
    """Brute-force spherical convolution of a lat-long map, evaluated at an output grid's texels."""
    src_dirs, sa = texel_grid(env.shape[0])
    src = env.reshape(-1, env.shape[2]).astype(np.float64) * sa[:, None]
    out_dirs, _ = texel_grid(out_height)
    out = np.empty((out_dirs.shape[0], env.shape[2]))
    for s in range(0, out_dirs.shape[0], chunk):
        out[s:s + chunk] = kernel(out_dirs[s:s + chunk] @ src_dirs.T) @ src
    return out.reshape(out_height, 2 * out_height, env.shape[2])


def box_downsample(env: np.ndarray, out_height: int) -> np.ndarray:
    """The specular reference: the solid-angle-weighted mean of the source over each output texel."""
    h = env.shape[0]
    f = h // out_height
    _, sa = texel_grid(h)
    sa = sa.reshape(h, 2 * h, 1)
    num = (env * sa).reshape(out_height, f, 2 * out_height, f, -1).sum(axis=(1, 3))
    den = sa.reshape(out_height, f, 2 * out_height, f, 1).sum(axis=(1, 3))
    return num / den


def reference_map(env: np.ndarray, name: str, out_height: int,
                  glossy1_exponent: float = 8.0, glossy2_exponent: float = 64.0,
                  ggx_roughness: float | None = None) -> np.ndarray:
    if name == "specular":
        return box_downsample(env, out_height)
    if ggx_roughness is not None:
        return convolve(env, ggx_kernel(ggx_roughness), out_height)
    exponent = {"diffuse": 1.0, "glossy1": glossy1_exponent, "glossy2": glossy2_exponent}[name]
    return convolve(env, phong_kernel(exponent), out_height)


def relative_rms(value: np.ndarray, reference: np.ndarray) -> float:
    """Solid-angle weighted RMS error relative to the reference's RMS (all channels)."""
    _, sa = texel_grid(reference.shape[0])
    w = sa.reshape(reference.shape[0], reference.shape[1], 1)
    err = np.sqrt((w * (value - reference) ** 2).sum() / w.sum())
    return float(err / np.sqrt((w * reference ** 2).sum() / w.sum()))
