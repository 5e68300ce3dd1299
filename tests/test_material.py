"""bpy-free material code: parameter ranges, JSON files (round trip and every bad input),
Principled conversion, presets and the shipped preset files."""
from __future__ import annotations

import dataclasses
import json
import math
import pathlib

import numpy as np
import pytest

import sbrdf_reference
import support  # noqa: F401  (makes `platelight` this checkout)
from platelight.addon.errors import PlateLightError
from platelight.addon.ibl import lobe_tilt
from platelight.addon.material import json_io, principled, presets
from platelight.addon.material.params import PARAMETERS, SBRDFParams

REPO = pathlib.Path(support.REPO)


def test_defaults_and_clamping():
    p = SBRDFParams(glossiness=3.0, fresnel_falloff=-1.0, diffuse_albedo=(2.0, -1.0, 0.5),
                    tangent_rotation=100.0).clamped()
    assert p.glossiness == 1.0 and p.fresnel_falloff == 0.0
    assert p.diffuse_albedo == (1.0, 0.0, 0.5)
    assert p.tangent_rotation == pytest.approx(2 * math.pi)
    assert {s.name for s in PARAMETERS} == {f.name for f in dataclasses.fields(SBRDFParams)}


def test_json_round_trip(tmp_path):
    p = presets.preset_params("brushed_metal")
    json_io.save_params(tmp_path / "m.json", p, "Brushed")
    back, name = json_io.load_params(tmp_path / "m.json")
    assert name == "Brushed" and back == p.clamped()


def _doc(**overrides):
    doc = json.loads(json_io.params_to_json(SBRDFParams()))
    doc.update(overrides)
    return json.dumps(doc)


@pytest.mark.parametrize("text, message", [
    ("{oops", "not valid JSON"),
    ("[1, 2]", "not a PlateLight SBRDF material"),
    (json.dumps({"format": "something-else", "version": 1}), "not a PlateLight SBRDF material"),
    (_doc(version=4), "version 4"),
    (_doc(version="1"), "no valid \"version\""),
    (_doc(parameters=[1]), "no \"parameters\""),
    (_doc(parameters={"shininess": 3}), "Unknown SBRDF parameter 'shininess'"),
    (_doc(parameters={"glossiness": "high"}), "glossiness must be a number"),
    (_doc(parameters={"glossiness": float("nan")}), "glossiness must be a number"),
    (_doc(parameters={"diffuse_albedo": [1, 2]}), "three numbers"),
])
def test_json_bad_input(text, message):
    with pytest.raises(PlateLightError, match=message):
        json_io.params_from_json(text)


def test_json_missing_file_and_partial_parameters(tmp_path):
    with pytest.raises(PlateLightError, match="File not found"):
        json_io.load_params(tmp_path / "nope.json")
    (tmp_path / "p.json").write_text(json.dumps(
        {"format": "platelight-sbrdf", "version": 1, "parameters": {"glossiness": 7}}))
    p, _ = json_io.load_params(tmp_path / "p.json")
    assert p.glossiness == 1.0 and p.cx == SBRDFParams().cx      # clamped, defaults kept
    # A version-1 file was made with the paper's cosine falloff: it keeps that look.
    assert p.paper_falloff == 1.0
    (tmp_path / "p2.json").write_text(json.dumps(
        {"format": "platelight-sbrdf", "version": 2, "parameters": {"glossiness": 0.5}}))
    assert json_io.load_params(tmp_path / "p2.json")[0].paper_falloff == 0.0
    # Files from before the Fresnel Peak (versions 1 and 2) keep the paper's f, which reaches 1.
    assert p.fresnel_peak == 1.0 and json_io.load_params(tmp_path / "p2.json")[0].fresnel_peak == 1.0
    saved = json.loads(json_io.params_to_json(SBRDFParams(fresnel_peak=0.2)))
    assert saved["version"] == 3 and saved["parameters"]["fresnel_peak"] == 0.2


def _median_angle(weights, theta):
    cdf = np.cumsum(weights * np.sin(theta))
    return theta[np.searchsorted(cdf / cdf[-1], 0.5)]


def _ggx_reflection_median(alpha, theta):
    """Half-energy angle of the directions a GGX surface reflects a head-on view into: microfacet
    normals at theta_h with density D(h) cos(theta_h), reflected to 2 theta_h."""
    a2 = alpha ** 2
    d = a2 / (np.pi * (np.cos(theta) ** 2 * (a2 - 1) + 1) ** 2)
    return 2 * _median_angle(d * np.cos(theta), theta)


def test_roughness_knots_match_the_ggx_lobes():
    """Each map's roughness is where GGX's reflection lobe is as wide (half its energy) as the map's
    Phong lobe (s = 64 glossy2, 8 glossy1, 1 diffuse): bisection on a dense angle grid."""
    theta = np.linspace(0.0, np.pi / 2, 200001)[:-1]
    for s, n in ((64, 2 / 3), (8, 1 / 3), (1, 0.0)):
        target = _median_angle(np.cos(theta) ** s, theta)
        lo, hi = 1e-3, 0.99
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if _ggx_reflection_median(mid, theta) < target else (lo, mid)
        roughness = np.sqrt((lo + hi) / 2)
        assert principled.glossiness_to_roughness(n) == pytest.approx(roughness, abs=0.002)
        assert principled.roughness_to_glossiness(roughness) == pytest.approx(n, abs=0.01)
    assert principled.roughness_to_glossiness(0.0) == 1.0
    assert principled.roughness_to_glossiness(1.0) == 0.0
    # a roughness-0.3 metal reads no mirror map (its sun is soft)
    assert principled.roughness_to_glossiness(0.3) < 2 / 3


def _dielectric_fresnel(cos_i, eta=1.5):
    g = np.sqrt(eta ** 2 - 1 + cos_i ** 2)
    a, b = (g - cos_i) / (g + cos_i), (cos_i * (g + cos_i) - 1) / (cos_i * (g - cos_i) + 1)
    return 0.5 * a ** 2 * (1 + b ** 2)


def _ggx_albedo(mu, alpha, n=256, fresnel=_dielectric_fresnel):
    """Directional albedo of a GGX dielectric (IOR 1.5; or any ``fresnel`` of cos(h, v)) seen at
    cos mu: the visible normals (Heitz 2018) on an n x n midpoint grid, each weighted by Fresnel
    and G2/G1."""
    wo = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    vh = np.array([alpha * wo[0], 0.0, wo[2]])
    vh /= np.linalg.norm(vh)
    t1_axis = np.array([0.0, 1.0, 0.0]) if vh[0] > 0 else np.array([1.0, 0.0, 0.0])
    t2_axis = np.cross(vh, t1_axis)
    u1, u2 = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    r, phi = np.sqrt(u1.ravel()), 2 * np.pi * u2.ravel()
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1 + vh[2])
    t2 = (1 - s) * np.sqrt(1 - t1 ** 2) + s * t2
    nh = (t1[:, None] * t1_axis + t2[:, None] * t2_axis
          + np.sqrt(np.maximum(0, 1 - t1 ** 2 - t2 ** 2))[:, None] * vh)
    h = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 1e-9)], -1)
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    d = h @ wo
    wi_z = 2 * d * h[:, 2] - mu

    def lam(c):
        c = np.clip(c, 1e-9, 1.0)
        return (np.sqrt(1 + alpha ** 2 * (1 - c ** 2) / c ** 2) - 1) / 2
    g2_over_g1 = np.where(wi_z > 0, (1 + lam(mu)) / (1 + lam(wi_z) + lam(mu)), 0.0)
    return float(np.mean(g2_over_g1 * fresnel(np.clip(d, 0, 1))))


def _multiscatter_albedo(mu, alpha, n=96):
    """The dielectric's albedo as Cycles' multiscatter GGX renders it: single scattering times
    1 + Fss (1 - E) / E, E the white albedo, Fss = (ior - 1) / (4.08567 + 1.00071 ior)."""
    white = _ggx_albedo(mu, alpha, n, fresnel=np.ones_like)
    return _ggx_albedo(mu, alpha, n) * (1 + 0.5 / (4.08567 + 1.00071 * 1.5) * (1 / white - 1))


def _specular_weight(s, mus):
    """The SBRDF's specular weight rho_s + (1 - rho_s) f at cos ``mus`` (red channel)."""
    return s.specular_albedo[0] + (1 - s.specular_albedo[0]) * sbrdf_reference.fresnel(dataclasses.asdict(s), mus)


def test_dielectric_fresnel_knots_follow_the_ggx_albedo():
    """At each roughness knot a dielectric's Fresnel Peak c and exponent k are the least-squares
    fit (projected area weighted) of c (1 - mu)^k to the rise of its albedo, (E(mu) - E(1)) /
    (1 - E(1)), and the factor on F0 is E(1) / F0; the converted material's specular weight then
    follows E within 0.01 + 3 % from cos 0.1 to 1 (c = 1 with one exponent missed it by up to
    0.17, at roughness 0.3)."""
    mus = np.linspace(0.02, 1.0, 50)
    exponents = np.linspace(0.5, 40.0, 396)
    for roughness, peak, exponent, head_on in zip(principled.DIELECTRIC_ROUGHNESS, principled.DIELECTRIC_PEAK,
                                                  principled.DIELECTRIC_EXPONENT, principled.DIELECTRIC_HEAD_ON):
        albedo = np.array([_multiscatter_albedo(mu, max(roughness ** 2, 1e-4)) for mu in mus])
        rise = (albedo - albedo[-1]) / (1 - albedo[-1])
        curves = (1 - mus)[None, :] ** exponents[:, None]
        peaks = np.clip((curves * rise * mus).sum(axis=1) / (curves ** 2 * mus).sum(axis=1), 0, 1)
        best = np.argmin((((peaks[:, None] * curves - rise) ** 2) * mus).sum(axis=1))
        assert peak == pytest.approx(peaks[best], rel=0.03, abs=0.003), roughness
        assert exponent == pytest.approx(exponents[best], abs=0.15), roughness
        assert head_on == pytest.approx(albedo[-1] / 0.04, abs=0.01), roughness
        s = principled.principled_to_sbrdf(principled.PrincipledValues(roughness=roughness))
        useful = mus >= 0.1
        assert (np.abs(_specular_weight(s, mus) - albedo) - 0.03 * albedo)[useful].max() < 0.01, roughness


def _metal_albedo(mu, alpha, f0, n=96):
    """A metal's albedo as Cycles' multiscatter GGX renders it: single scattering with Schlick's
    Fresnel from F0 times 1 + F_avg (1 - W) / W, W the white albedo, F_avg = F0 + (1 - F0) / 21."""
    white = _ggx_albedo(mu, alpha, n, fresnel=np.ones_like)
    schlick = lambda c: f0 + (1 - f0) * (1 - np.clip(c, 0, 1)) ** 5  # noqa: E731
    return _ggx_albedo(mu, alpha, n, fresnel=schlick) * (1 + (f0 + (1 - f0) / 21) * (1 - white) / white)


def test_metal_fresnel_knots_follow_the_ggx_albedo():
    """A metal's Fresnel Peak c and exponent k at each roughness knot are the least-squares fit
    (projected area weighted, relative error, F0 0.3-0.9) of c (1 - mu)^k to the rise of its
    multiscatter albedo, (E(mu) - E(1)) / (1 - E(1)); the converted metal's specular weight then
    follows E within 4 % from cos 0.1 to 1 up to roughness 0.7 (c = 1 with one exponent, as
    before, missed it by 25 % at roughness 0.3: too dark at cos 0.4, too bright at 0.1)."""
    mus = np.linspace(0.05, 1.0, 25)
    f0s = np.array([0.3, 0.5, 0.7, 0.9])
    weights = mus * (mus >= 0.1)
    exponents = np.linspace(1.0, 12.0, 1101)
    curves = (1 - mus)[None, :] ** exponents[:, None]
    for roughness, peak, exponent in zip(principled.FALLOFF_ROUGHNESS, principled.FALLOFF_PEAK,
                                         principled.FALLOFF_EXPONENT):
        alpha = max(roughness ** 2, 1e-4)
        albedo = np.array([[_metal_albedo(mu, alpha, f0) for mu in mus] for f0 in f0s])
        head_on = albedo[:, -1:]
        rise = (albedo - head_on) / (1 - head_on)
        relative = ((1 - head_on) / albedo) ** 2 * weights

        def cost(c, k):
            return (((c * (1 - mus) ** k - rise) ** 2) * relative).sum()
        peaks = np.clip((curves[:, None] * rise * relative).sum((1, 2))
                        / (curves[:, None] ** 2 * relative).sum((1, 2)), 0, 1)
        best = ((((peaks[:, None, None] * curves[:, None] - rise) ** 2) * relative).sum((1, 2))).min()
        assert cost(peak, exponent) <= 1.05 * best + 1e-7, roughness
        s = principled.principled_to_sbrdf(principled.PrincipledValues(
            base_color=tuple(f0s[:3]), metallic=1.0, roughness=roughness))
        assert s.fresnel_peak == pytest.approx(peak) and 1 / s.fresnel_falloff - 1 == pytest.approx(exponent)
        weight = head_on + (1 - head_on) * peak * (1 - mus) ** exponent
        miss = np.abs(weight / albedo - 1)[:, mus >= 0.1].max()
        assert miss < (0.04 if roughness <= 0.7 else 0.06 if roughness <= 0.8 else 0.1), roughness
    # polished: Schlick's curve
    assert principled.roughness_to_fresnel_falloff(0.0) == pytest.approx(1 / 6, rel=0.01)
    assert principled.metal_fresnel_peak(0.0) == 1.0


def test_metal_head_on_follows_the_multiscatter_albedo():
    """A metal's specular albedo is base x E(1)/F0 of Cycles' multiscatter GGX: single scattering
    (Schlick's Fresnel from F0 = base) scaled by 1 + F_avg (1 - W) / W, W the white single-scattering
    albedo (brute force over visible normals). The table holds W head-on at each knot; the
    converted metal follows E(1) within 1.5 % for F0 0.3-0.95 (it took F0 itself: 25 % too much
    for F0 0.7 at roughness 1)."""
    for roughness, white in zip(principled.FALLOFF_ROUGHNESS, principled.WHITE_HEAD_ON):
        alpha = max(roughness ** 2, 1e-4)
        w = _ggx_albedo(1.0, alpha, 256, fresnel=np.ones_like)
        assert white == pytest.approx(w, abs=0.002), roughness
        for f0 in (0.3, 0.7, 0.95):
            multi = _metal_albedo(1.0, alpha, f0, 256)
            s = principled.principled_to_sbrdf(principled.PrincipledValues(
                base_color=(f0,) * 3, metallic=1.0, roughness=roughness))
            assert s.specular_albedo[0] == pytest.approx(multi, rel=0.015), (roughness, f0)
    rough = principled.principled_to_sbrdf(principled.PrincipledValues(
        base_color=(0.7,) * 3, metallic=1.0, roughness=1.0))
    assert rough.specular_albedo[0] == pytest.approx(0.7 * 0.802, abs=0.005)


@pytest.mark.parametrize("values", [
    principled.PrincipledValues(base_color=(0.9, 0.2, 0.1), metallic=0.0, roughness=0.3),
    principled.PrincipledValues(base_color=(0.95, 0.64, 0.54), metallic=1.0, roughness=0.1),
    principled.PrincipledValues(base_color=(1, 1, 1), transmission=1.0, roughness=0.0, ior=1.45),
    principled.PrincipledValues(emission_color=(1, 0.5, 0.2), emission_strength=5.0),
    # rougher than the diffuse map: the roughness comes back from the peak's pull to the normal
    principled.PrincipledValues(base_color=(0.7, 0.7, 0.7), roughness=1.0),
    principled.PrincipledValues(base_color=(0.9, 0.6, 0.2), metallic=1.0, roughness=0.8),
])
def test_principled_round_trip(values):
    s = principled.principled_to_sbrdf(values)
    back = principled.sbrdf_to_principled(s)
    assert back.base_color == pytest.approx(values.base_color, abs=1e-6)
    assert back.metallic == values.metallic
    assert back.roughness == pytest.approx(values.roughness, abs=1e-6)
    assert back.transmission == pytest.approx(values.transmission)
    assert back.ior == pytest.approx(values.ior)
    assert back.emission_strength == values.emission_strength
    assert back.anisotropic == 0.0


def test_a_rough_lobe_peaks_at_the_normal():
    """Up to the diffuse map's roughness the peak is the mirror direction (Cx = Cy = -1); beyond
    it the peak is pulled to the normal, all the way at roughness 1 (Cx = Cy = 0). Brute force:
    the centroid of the light a GGX lobe reflects (D(h) G2, directions above the horizon) climbs
    towards N as the roughness grows past the diffuse map's, and at roughness 1 it is N at every
    view, so no view-dependent direction can serve that lobe better than the normal."""
    knot = float(principled.maps.ROUGHNESS_KNOTS[0])
    for roughness, pull in ((0.3, 0.0), (knot, 0.0), ((knot + 1) / 2, 0.5), (1.0, 1.0)):
        s = principled.principled_to_sbrdf(principled.PrincipledValues(roughness=roughness))
        assert (s.cx, s.cy, s.cz) == pytest.approx((pull - 1.0, pull - 1.0, 1.0)), roughness
        assert s.glossiness == pytest.approx(principled.roughness_to_glossiness(roughness))
    for mu in (0.1, 0.4, 0.8):
        elevations = [np.degrees(np.arcsin(lobe_tilt.kept_lobe_centroid(r, mu, 128)[2]))
                      for r in (knot, (knot + 1) / 2, 1.0)]
        assert elevations[0] < elevations[1] < elevations[2], mu
        assert elevations[2] > 89.0, mu


def test_principled_mapping_values():
    s = principled.principled_to_sbrdf(principled.PrincipledValues(
        base_color=(0.5, 0.5, 0.5), metallic=0.0, ior=1.5, specular_ior_level=0.5))
    # F0 of IOR 1.5 less what masking takes head-on at roughness 0.5 (the default)
    assert s.specular_albedo == pytest.approx((0.04 * 0.934,) * 3)
    assert s.diffuse_albedo == pytest.approx((0.5,) * 3)
    # ... and its rise towards grazing reaches 18 %, not the mirror's 100 %
    assert (s.fresnel_peak, 1 / s.fresnel_falloff - 1) == pytest.approx((0.181, 2.5), rel=0.01)
    metal = principled.principled_to_sbrdf(principled.PrincipledValues(metallic=1.0, roughness=0.5))
    # a rough metal's rim brightens by a quarter of the way to white, not all of it
    assert (metal.fresnel_peak, 1 / metal.fresnel_falloff - 1) == pytest.approx((0.255, 5.22), rel=0.01)
    # GGX anisotropy stays Anisotropy (the group stretches the lobe), its peak at the mirror direction
    brushed = principled.principled_to_sbrdf(principled.PrincipledValues(
        metallic=1.0, roughness=0.3, anisotropic=0.8, anisotropic_rotation=0.25))
    assert (brushed.cx, brushed.cy, brushed.cz) == (-1.0, -1.0, 1.0)
    assert brushed.glossiness == pytest.approx(principled.roughness_to_glossiness(0.3))
    assert brushed.anisotropy == pytest.approx(0.8)
    assert brushed.tangent_rotation == pytest.approx(np.pi / 2)
    assert principled.sbrdf_to_principled(brushed).anisotropic == pytest.approx(0.8)
    metal = principled.principled_to_sbrdf(principled.PrincipledValues(
        base_color=(0.9, 0.6, 0.2), metallic=1.0))
    assert metal.diffuse_albedo == (0.0, 0.0, 0.0)
    # F0 less what multiscatter GGX does not give back at roughness 0.5 (the default)
    assert metal.specular_albedo == pytest.approx((0.9 * 0.992, 0.6 * 0.968, 0.2 * 0.936), abs=1e-3)


def test_presets_cover_the_paper_and_files_are_current(tmp_path):
    assert set(presets.PRESETS) == {"chrome", "brushed_metal", "glass", "plastic", "rubber",
                                    "polished_paint", "marble", "emissive"}
    bm = presets.preset_params("brushed_metal")
    assert abs(bm.cx) != abs(bm.cy)                   # anisotropic
    assert presets.preset_params("glass").alpha == 0.0
    assert presets.preset_params("emissive").emission_strength > 1.0
    with pytest.raises(PlateLightError, match="Unknown SBRDF preset"):
        presets.preset_params("velvet")
    # The shipped preset scripts are generated from PRESETS and must not drift.
    written = presets.write_preset_files(tmp_path)
    for path in map(pathlib.Path, written):
        shipped = REPO / "presets" / presets.PRESET_SUBDIR / path.name
        assert shipped.read_text() == path.read_text(), f"regenerate {shipped.name}"


def test_changes_names_every_parameter_each_principled_input_moves():
    """principled.CHANGES decides which SBRDF sockets a texture-driven Principled input drives:
    one it misses would keep a constant where the texture varies, one too many would take a
    slider from the material editor. Each input is nudged at random points of the others."""
    rng = np.random.default_rng(7)
    moved = {field: set() for field in principled.CHANGES}
    for _ in range(40):
        values = principled.PrincipledValues(
            base_color=tuple(rng.uniform(0.05, 0.95, 3)), metallic=float(rng.uniform(0.05, 0.95)),
            roughness=float(rng.uniform(0.05, 0.95)), ior=float(rng.uniform(1.1, 2.5)),
            specular_ior_level=float(rng.uniform(0.1, 0.9)),
            transmission=float(rng.uniform(0.05, 0.95)), alpha=float(rng.uniform(0.1, 0.9)),
            anisotropic=float(rng.uniform(0.05, 0.95)),
            anisotropic_rotation=float(rng.uniform(0.05, 0.95)),
            emission_color=tuple(rng.uniform(0.05, 0.95, 3)),
            emission_strength=float(rng.uniform(0.5, 5.0)))
        before = dataclasses.asdict(principled.principled_to_sbrdf(values))
        for field in principled.CHANGES:
            value = getattr(values, field)
            nudged = tuple(c * 0.93 for c in value) if isinstance(value, tuple) else value * 0.93
            after = dataclasses.asdict(principled.principled_to_sbrdf(
                dataclasses.replace(values, **{field: nudged})))
            moved[field] |= {name for name in before
                             if not np.allclose(before[name], after[name], atol=1e-9)}
    assert set(principled.CHANGES) == {f.name for f in dataclasses.fields(principled.PrincipledValues)}
    for field, changed in principled.CHANGES.items():
        assert moved[field] == set(changed), field
