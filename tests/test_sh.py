"""Spherical harmonics: basis convention, orthonormality to degree 30, exact projection."""
import numpy as np
import pytest

import support  # noqa: F401  (points `platelight` at this checkout)
from platelight.addon.ibl import sh
from platelight.addon.ibl.equirect import texel_directions


def gauss_sphere_quadrature(lmax):
    """Gauss–Legendre in cos θ × uniform in φ: exact for products of SH up to degree lmax."""
    n = lmax + 2
    x, w = np.polynomial.legendre.leggauss(n)
    phi = 2 * np.pi * np.arange(2 * n + 2) / (2 * n + 2)
    st = np.sqrt(1 - x * x)
    d = np.stack([np.outer(st, np.cos(phi)), np.outer(st, np.sin(phi)),
                  np.outer(x, np.ones_like(phi))], -1).reshape(-1, 3)
    weights = np.outer(w, np.full(phi.size, 2 * np.pi / phi.size)).ravel()
    return d, weights


def test_basis_matches_ramamoorthi_hanrahan_polynomials():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    x, y, z = d.T
    expected = np.stack([
        np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
        1.092548 * x * z, 0.546274 * (x * x - y * y)], axis=1)
    np.testing.assert_allclose(sh.sh_basis(2, d), expected, atol=2e-6)


def test_orthonormal_to_degree_30():
    d, w = gauss_sphere_quadrature(30)
    y = sh.sh_basis(30, d)
    gram = (y * w[:, None]).T @ y
    assert np.abs(gram - np.eye(gram.shape[0])).max() < 1e-10


def test_finite_at_poles_and_seams():
    d = np.array([[0, 0, 1], [0, 0, -1], [-1, 0, 0], [-1, 1e-17, 0], [-1, -1e-17, 0],
                  [1e-300, 0, 1], [0, 0, 1 + 1e-16]], dtype=float)
    y = sh.sh_basis(40, d)
    assert np.isfinite(y).all()
    # At the poles only m = 0 survives.
    for l in range(1, 41):
        row = np.delete(y[0, l * l:(l + 1) ** 2], l)
        assert np.abs(row).max() < 1e-12


def band_limited_env(lmax, height, seed=3):
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(size=((lmax + 1) ** 2, 3))
    d = texel_directions(height, 2 * height).reshape(-1, 3)
    return coeffs, (sh.sh_basis(lmax, d) @ coeffs).reshape(height, 2 * height, 3)


@pytest.mark.parametrize("lmax,height", [(2, 8), (15, 32), (30, 64)])
def test_exact_projection_recovers_band_limited_coefficients(lmax, height):
    coeffs, env = band_limited_env(lmax, height)
    got = sh.project_exact(env, lmax + 1)
    rel = np.abs(got[: coeffs.shape[0]] - coeffs).max() / np.abs(coeffs).max()
    assert rel <= 1e-6
    assert np.abs(got[coeffs.shape[0]:]).max() <= 1e-6 * np.abs(coeffs).max()


def test_synthesis_inverts_projection():
    coeffs, env = band_limited_env(12, 32)
    np.testing.assert_allclose(sh.synthesize(coeffs, 32), env, atol=1e-10)


def test_lobe_factors():
    # Ramamoorthi–Hanrahan: A_l/π = 1, 2/3, 1/4, 0, −1/24 for the clamped cosine.
    np.testing.assert_allclose(sh.lobe_factors(1, 4), [1, 2 / 3, 1 / 4, 0, -1 / 24], atol=1e-12)
    # Closed form for l = 1: (s+1)/(s+2).
    for s in (8, 64, 500):
        assert sh.lobe_factors(s, 1)[1] == pytest.approx((s + 1) / (s + 2), rel=1e-10)


def test_paper_directions_are_stratified_and_uniform():
    d = sh.paper_directions(4096, seed=1)
    assert d.shape == (4096, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, atol=1e-12)
    # Uniform on the sphere: z is uniform in [-1, 1], so its mean is ~0 and E[z²] = 1/3.
    assert abs(d[:, 2].mean()) < 5e-3 and abs((d[:, 2] ** 2).mean() - 1 / 3) < 5e-3
    # Same seed, same directions; different seed, different jitter.
    np.testing.assert_array_equal(d, sh.paper_directions(4096, seed=1))
    assert not np.allclose(d, sh.paper_directions(4096, seed=2))


def test_lobe_degree_keeps_odd_factors_of_even_exponents():
    """s = 8: λ_10 vanishes exactly but λ_11 does not; the series must not stop at 10."""
    from platelight.addon.ibl import maps
    factors = sh.lobe_factors(8.0, 40)
    assert abs(factors[10]) < 1e-12 and abs(factors[11]) > 1e-5
    degree = maps.lobe_lmax(8.0, 511)
    assert np.all(np.abs(factors[degree + 1:]) < maps.LOBE_CUTOFF) and degree >= 19
