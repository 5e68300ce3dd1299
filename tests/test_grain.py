"""Grain matching engine (addon/compositing/grain.py): the estimate recovers known synthetic grain
(white and correlated, per channel, signal-dependent) on a smooth image with an edge; make_grain
has the requested statistics, repeats per (seed, frame) and changes between frames; bad input."""
import numpy as np
import pytest

import support  # noqa: F401
from platelight.addon.compositing.grain import GrainStats, estimate_grain, grain_correlation, make_grain
from platelight.addon.errors import PlateLightError

N = 384


def correlated_noise(rng, size, n=N):
    """Unit-variance noise, white or blurred by a continuous Gaussian of std ``size`` px (done
    in the Fourier domain: independent of the module's discrete kernel)."""
    noise = rng.standard_normal((n, n))
    if size > 0:
        f = np.fft.fftfreq(n)
        transfer = np.exp(-2 * np.pi ** 2 * size ** 2 * (f[:, None] ** 2 + f[None, :] ** 2))
        noise = np.real(np.fft.ifft2(np.fft.fft2(noise) * transfer))
    return noise / noise.std()


def smooth_image(n=N):
    """Shading with a gradient, slow waves and a bright band with hard edges."""
    y, x = np.mgrid[0:n, 0:n] / n
    base = 0.3 + 0.25 * np.sin(2 * np.pi * 1.5 * x) * np.cos(2 * np.pi * y) + 0.2 * x
    base[n // 3:n // 2] += 0.3
    return np.stack([base, 0.8 * base + 0.1, 0.5 * base + 0.2], axis=-1)


@pytest.mark.parametrize("size", [0.0, 1.0, 1.5, 2.5])
@pytest.mark.parametrize("sigma", [(0.01, 0.02, 0.04), (0.003, 0.003, 0.006)])
def test_estimate_recovers_constant_grain(size, sigma):
    rng = np.random.default_rng(int(size * 10) + int(sigma[0] * 1e4))
    noise = np.stack([correlated_noise(rng, size) for _ in range(3)], axis=-1)
    stats = estimate_grain((smooth_image() + np.array(sigma) * noise).astype(np.float32))
    np.testing.assert_allclose(stats.sigma, sigma, rtol=0.10)
    assert abs(stats.size - size) < 0.15 + 0.1 * size
    assert np.all(stats.response < 0.25)          # no signal dependence to find
    assert stats.pixels > 0.3 * N * N


def test_estimate_recovers_signal_dependent_grain():
    rng = np.random.default_rng(7)
    image = smooth_image()
    floor, slope = np.array([1e-5, 4e-6, 2e-5]), np.array([4e-4, 2e-4, 1e-3])
    noise = np.stack([correlated_noise(rng, 1.0) for _ in range(3)], axis=-1)
    plate = image + np.sqrt(floor + slope * image) * noise
    stats = estimate_grain(plate.astype(np.float32))
    for level in (0.2, stats.level, 0.7):
        np.testing.assert_allclose(stats.sigma_at(level), np.sqrt(floor + slope * level), rtol=0.10)
    np.testing.assert_allclose(stats.sigma, stats.sigma_at(stats.level), rtol=1e-9)
    assert np.all(stats.response > 0.7)           # mostly shot noise
    assert abs(stats.size - 1.0) < 0.2


@pytest.mark.parametrize("seed", range(5))
def test_constant_grain_on_a_small_plate_gets_no_signal_dependence(seed):
    """A noisy slope would be extrapolated to the CG's level: it must be significant to count."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:108, 0:192]
    base = (0.3 + 0.3 * x / 192 + 0.1 * y / 108)[..., None] * np.array([1.0, 0.9, 0.8])
    stats = estimate_grain((base + 0.03 * rng.standard_normal((108, 192, 3))).astype(np.float32))
    assert np.all(stats.response == 0)
    np.testing.assert_allclose(stats.sigma, 0.03, rtol=0.10)


def test_make_grain_statistics_and_determinism():
    stats = GrainStats.constant((0.01, 0.02, 0.05), size=1.5)
    a = make_grain(stats, 320, 240, frame=3, seed=11)
    assert a.dtype == np.float32 and a.shape == (240, 320, 3)
    np.testing.assert_allclose(a.std(axis=(0, 1)), stats.sigma, rtol=0.08)
    assert np.all(np.abs(a.mean(axis=(0, 1))) < 0.1 * stats.sigma)
    lag1 = [np.corrcoef(a[:, 1:, c].ravel(), a[:, :-1, c].ravel())[0, 1] for c in range(3)]
    np.testing.assert_allclose(lag1, grain_correlation(1.5), atol=0.03)
    # the estimator reads back what make_grain made
    back = estimate_grain(0.5 + make_grain(stats, 384, 384, frame=1, seed=2))
    np.testing.assert_allclose(back.sigma, stats.sigma, rtol=0.10)
    assert abs(back.size - 1.5) < 0.2
    np.testing.assert_array_equal(a, make_grain(stats, 320, 240, frame=3, seed=11))
    other = make_grain(stats, 320, 240, frame=4, seed=11)
    assert abs(np.corrcoef(a.ravel(), other.ravel())[0, 1]) < 0.02      # independent frames
    assert not np.array_equal(a, make_grain(stats, 320, 240, frame=3, seed=12))
    white = make_grain(GrainStats.constant(0.1), 200, 200, frame=-5, seed=0)
    assert abs(np.corrcoef(white[:, 1:, 0].ravel(), white[:, :-1, 0].ravel())[0, 1]) < 0.03


def test_no_grain_and_odd_pixels():
    flat = np.full((64, 64, 3), 0.25, np.float32)
    stats = estimate_grain(flat)
    assert np.all(stats.sigma == 0) and stats.size == 0.0
    zero = make_grain(stats, 16, 8, frame=1, seed=0)
    assert zero.shape == (8, 16, 3) and not zero.any()
    # NaN/Inf holes and negative pixels: ignored / kept, the estimate stays right and finite
    rng = np.random.default_rng(3)
    plate = (0.02 * rng.standard_normal((256, 256, 3))).astype(np.float32)   # half negative
    plate[40:50, 40:50] = np.nan
    plate[100, :, 1] = np.inf
    plate[200:, 200:] = -np.inf
    stats = estimate_grain(plate)
    np.testing.assert_allclose(stats.sigma, 0.02, rtol=0.10)
    assert np.all(np.isfinite(make_grain(stats, 64, 64, frame=1, seed=0)))
    # RGBA and integer plates
    assert estimate_grain(np.dstack([plate, np.ones((256, 256))])).sigma[0] == stats.sigma[0]
    assert estimate_grain((rng.random((64, 64, 3)) * 255).astype(np.uint8)).sigma[0] > 0


@pytest.mark.parametrize("plate,message", [
    (np.zeros((8, 64, 3)), "too small"),
    (np.zeros((64, 64)), "RGB image"),
    (np.full((64, 64, 3), np.nan), "no usable pixels"),
    (np.random.default_rng(0).uniform(-3e38, 3e38, (64, 64, 3)).astype(np.float32), "no usable pixels"),
    (np.array([["a"] * 3] * 64 * 64).reshape(64, 64, 3), "numbers"),
])
def test_estimate_bad_input(plate, message):
    with pytest.raises(PlateLightError, match=message):
        estimate_grain(plate)


@pytest.mark.parametrize("kwargs,message", [
    (dict(width=0), "width"), (dict(height=10 ** 6), "height"), (dict(width=2.5), "whole number"),
    (dict(width=30000, height=30000), "too large"), (dict(frame=1.5), "frame"),
])
def test_make_grain_bad_input(kwargs, message):
    args = dict(width=8, height=8, frame=1, seed=0) | kwargs
    with pytest.raises(PlateLightError, match=message):
        make_grain(GrainStats.constant(0.1), **args)
    for bad in (dict(sigma=-1.0), dict(sigma=np.nan), dict(sigma=0.1, size=50.0)):
        with pytest.raises(PlateLightError, match="Grain"):
            GrainStats.constant(**bad)
