"""The bpy-free half of probe baking: frame ranges, content hashes, map needs, frustum culling,
folder names and bake records."""
from __future__ import annotations

import math
import os

import numpy as np
import pytest

import support  # noqa: F401  (imports this checkout as `platelight`)
from platelight.addon.bake import culling, frames, hashing, layout, needs, probe_reuse
from platelight.addon.errors import PlateLightError
from platelight.addon.ibl.maps import MAP_GLOSSINESS, MAP_NAMES, footprint_glossiness, map_weights, tent_weights


# ---------------------------------------------------------------- frames

def test_parse_frames():
    assert frames.parse_frames("10-20") == list(range(10, 21))
    assert frames.parse_frames("7") == [7]
    assert frames.parse_frames("1-3, 8,2") == [1, 2, 3, 8]
    assert frames.parse_frames("-2-1") == [-2, -1, 0, 1]


@pytest.mark.parametrize("text", ["", "a-b", "5-2", "1-", "1-200000"])
def test_parse_frames_rejects(text):
    with pytest.raises(PlateLightError):
        frames.parse_frames(text)


@pytest.mark.parametrize("n, parts", [(11, 3), (10, 4), (3, 5), (100, 7)])
def test_split_covers_every_frame_once(n, parts):
    all_frames = list(range(10, 10 + n))
    chunks = [frames.split_frames(all_frames, i, parts) for i in range(1, parts + 1)]
    assert sum(chunks, []) == all_frames
    assert max(map(len, chunks)) - min(map(len, chunks)) <= 1


def test_split_rejects_missing_part():
    with pytest.raises(PlateLightError, match="does not exist"):
        frames.split_frames([1, 2], 3, 2)


# ---------------------------------------------------------------- hashing

def test_hash_is_stable_and_ignores_float_noise():
    matrix = np.eye(4) * 1.2345
    a = hashing.content_hash({"m": matrix, "x": 0.1 + 0.2, "names": ["a", "b"]})
    b = hashing.content_hash({"names": ["a", "b"], "x": 0.3, "m": matrix * (1 + 1e-9)})
    assert a == b and len(a) == 40


@pytest.mark.parametrize("change", [
    {"m": np.eye(4) * 1.2345 + np.eye(4)[0] * 1e-3},      # a millimetre move
    {"x": 0.31}, {"names": ["b", "a"]}, {"extra": None}, {"m": np.eye(3) * 1.2345}])
def test_hash_sees_real_changes(change):
    base = {"m": np.eye(4) * 1.2345, "x": 0.3, "names": ["a", "b"]}
    assert hashing.content_hash(base) != hashing.content_hash({**base, **change})


def test_hash_of_arrays_is_cheap_for_big_meshes():
    """A cache hit must stay well under 10 ms: hashing 100k vertices is part of it."""
    import time

    co = np.random.default_rng(0).random(300_000).astype(np.float32)
    t0 = time.perf_counter()
    hashing.content_hash({"co": co})
    assert time.perf_counter() - t0 < 0.5      # generous: only guards against an O(n) Python loop


# ---------------------------------------------------------------- which maps

@pytest.mark.parametrize("lobes, expected", [
    (needs.Lobes(diffuse=True, specular=False, glossiness=0.5, fresnel=False), ("diffuse",)),
    (needs.Lobes(diffuse=False, specular=True, glossiness=1.0, fresnel=True), ("specular",)),
    # with Fresnel off too: near a contact the glossy footprint sharpens the look-up to the mirror
    (needs.Lobes(diffuse=False, specular=True, glossiness=1 / 3, fresnel=False),
     ("glossy1", "glossy2", "specular")),
    (needs.Lobes(diffuse=False, specular=True, glossiness=0.5, fresnel=False),
     ("glossy1", "glossy2", "specular")),
    (needs.Lobes(diffuse=False, specular=True, glossiness=0.0, fresnel=False), ("diffuse",)),
    (needs.Lobes(diffuse=False, specular=True, glossiness=0.5, fresnel=True),
     ("glossy1", "glossy2", "specular")),
    (needs.Lobes(diffuse=True, specular=False, glossiness=0.0, fresnel=True), needs.MAP_NAMES),
    (needs.Lobes(diffuse=False, specular=True, glossiness=None, fresnel=False), needs.MAP_NAMES),
    (needs.Lobes(diffuse=False, specular=False, glossiness=1.0, fresnel=False), ("diffuse",)),
    # an anisotropic lobe reads its narrow axis's sharper maps; a textured anisotropy, any
    (needs.Lobes(diffuse=False, specular=True, glossiness=2 / 3, fresnel=False, anisotropy=0.8),
     ("glossy2", "specular")),
    (needs.Lobes(diffuse=False, specular=True, glossiness=2 / 3, fresnel=False, anisotropy=None),
     needs.MAP_NAMES),
])
def test_maps_needed(lobes, expected):
    assert needs.maps_needed([lobes]) == expected


def test_maps_needed_unions_materials_and_defaults_to_all():
    matte = needs.Lobes(True, False, 0.0, False)
    mirror = needs.Lobes(False, True, 1.0, False)
    assert needs.maps_needed([matte, mirror]) == ("diffuse", "specular")
    assert needs.maps_needed([]) == needs.MAP_NAMES


def test_owner_visibility_follows_how_sharply_the_owner_reflects():
    """A sharp reflector's or a glossy metal's probe shows the floor under it as it is (the owner
    blocks and bounces its indirect light); an object with a diffuse term, or a rough metal, keeps
    the shadow-only owner; the paper's setting hides it whatever it is."""
    mirror = needs.Lobes(diffuse=False, specular=True, glossiness=0.9, fresnel=True)
    copper = needs.Lobes(diffuse=False, specular=True, glossiness=0.6, fresnel=True)
    matte = needs.Lobes(diffuse=True, specular=False, glossiness=0.0, fresnel=False)
    textured = needs.Lobes(diffuse=True, specular=True, glossiness=None, fresnel=True)
    assert needs.owner_visibility([mirror], True) == needs.OWNER_INDIRECT
    assert needs.owner_visibility([matte, mirror], True) == needs.OWNER_INDIRECT
    assert needs.owner_visibility([textured], True) == needs.OWNER_INDIRECT
    glossy_plastic = needs.Lobes(diffuse=True, specular=True, glossiness=0.6, fresnel=True)
    rough_black = needs.Lobes(diffuse=False, specular=True, glossiness=0.0, fresnel=True)
    assert needs.owner_visibility([copper], True) == needs.OWNER_INDIRECT
    assert needs.owner_visibility([copper, glossy_plastic], True) == needs.OWNER_SHADOWS
    assert needs.owner_visibility([rough_black], True) == needs.OWNER_SHADOWS
    # a metal whose lobe reads the diffuse map (rougher than glossy1's 0.443) keeps the shadow-only
    # owner: its wide lobe would blur the darkened floor under it over its lower half
    at_glossy1 = needs.Lobes(diffuse=False, specular=True, glossiness=1 / 3, fresnel=True)
    satin = needs.Lobes(diffuse=False, specular=True, glossiness=0.3, fresnel=True)
    assert needs.owner_visibility([at_glossy1], True) == needs.OWNER_INDIRECT
    assert needs.owner_visibility([satin], True) == needs.OWNER_SHADOWS
    assert needs.owner_visibility([matte], True) == needs.OWNER_SHADOWS
    assert needs.owner_visibility([], True) == needs.OWNER_SHADOWS
    for lobes in ([mirror], [matte], []):
        assert needs.owner_visibility(lobes, False) == needs.OWNER_HIDDEN


def test_map_weights_blend_neighbouring_anchors():
    """The one glossiness rule: weights sum to 1, at most two neighbours are non-zero, and the
    map anchored at n has weight 1 there."""
    assert MAP_GLOSSINESS == {"diffuse": 0.0, "glossy1": 1 / 3, "glossy2": 2 / 3, "specular": 1.0}
    for name, anchor in MAP_GLOSSINESS.items():
        assert map_weights(anchor)[name] == 1.0
    for n in np.linspace(-0.2, 1.2, 141):
        weights = map_weights(n)
        assert abs(sum(weights.values()) - 1.0) < 1e-12, n
        used = [i for i, name in enumerate(MAP_NAMES) if weights[name] > 0]
        assert 1 <= len(used) <= 2 and used[-1] - used[0] <= 1, (n, weights)
    assert map_weights(0.5) == pytest.approx({"diffuse": 0, "glossy1": 0.5, "glossy2": 0.5, "specular": 0})


def test_glossiness_reads_its_anchor_neighbours_and_the_sharper_maps_its_footprint_reaches():
    """Every glossiness reads the maps whose anchors bracket it (design.md's blend) and, above 0,
    every sharper one: the glossy footprint can narrow the look-up up to the mirror map, and an
    unbaked map would read black there."""
    for n in np.linspace(0, 1, 61):
        got = needs.glossy_maps(n, fresnel=False)
        anchors = sorted(MAP_GLOSSINESS.items(), key=lambda kv: kv[1])
        upper = min((a for a in anchors if a[1] >= n - 1e-12), key=lambda kv: kv[1])
        lower = max((a for a in anchors if a[1] <= n + 1e-12), key=lambda kv: kv[1])
        assert {lower[0], upper[0]} <= got, n
        sharper = set(MAP_NAMES[MAP_NAMES.index(lower[0]):]) if n > 0 else {lower[0]}
        assert got == sharper, n
        # the footprint's narrowest look-up for this lobe lies among them
        narrowest = float(footprint_glossiness(n, 0.0))
        assert all(w == 0 or name in got for name, w in zip(MAP_NAMES, tent_weights(narrowest))), n


# ---------------------------------------------------------------- culling

def _look_at(eye, target):
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0, 0, 1], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
    return m


def _inside_by_projection(m, half_w, half_h, near, far, p):
    """Independent reference: project into the camera and compare with the film rectangle."""
    local = np.linalg.inv(m) @ np.append(p, 1.0)
    depth = -local[2]
    if not near <= depth <= far:
        return False
    return abs(local[0] / depth) <= half_w and abs(local[1] / depth) <= half_h


def test_frustum_points_agree_with_projection():
    rng = np.random.default_rng(1)
    m = _look_at((4, -6, 2), (0, 0, 0.5))
    half_w, half_h = 0.5 / 1.4, 0.28 / 1.4
    corners = [(0.5, 0.28, -1.4), (0.5, -0.28, -1.4), (-0.5, -0.28, -1.4), (-0.5, 0.28, -1.4)]
    planes = culling.frustum_planes(m, corners, 0.1, 30.0)
    points = rng.uniform(-15, 15, size=(4000, 3))
    got = np.array([culling.sphere_in_frustum(planes, p, 0.0) for p in points])
    ref = np.array([_inside_by_projection(m, half_w, half_h, 0.1, 30.0, p) for p in points])
    assert got.sum() > 100 and (got == ref).all()


def test_frustum_sphere_never_culls_a_visible_sphere():
    rng = np.random.default_rng(2)
    m = _look_at((0, -10, 1), (0, 0, 1))
    corners = [(0.4, 0.3, -1), (0.4, -0.3, -1), (-0.4, -0.3, -1), (-0.4, 0.3, -1)]
    planes = culling.frustum_planes(m, corners, 0.1, 100.0)
    for _ in range(300):
        centre = rng.uniform(-12, 12, 3)
        radius = rng.uniform(0.1, 3)
        dirs = rng.normal(size=(200, 3))
        surface = centre + radius * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        visible = any(_inside_by_projection(m, 0.4, 0.3, 0.1, 100.0, p) for p in surface)
        if visible:
            assert culling.sphere_in_frustum(planes, centre, radius)
    # Far outside one plane: culled.
    assert not culling.sphere_in_frustum(planes, (0, -20, 1), 1.0)      # behind the camera
    assert not culling.sphere_in_frustum(planes, (50, 0, 1), 1.0)       # far to the side


def test_orthographic_frustum():
    m = _look_at((0, -10, 0), (0, 0, 0))
    corners = [(2, 1, -1), (2, -1, -1), (-2, -1, -1), (-2, 1, -1)]
    planes = culling.frustum_planes(m, corners, 0.1, 50.0, orthographic=True)
    assert culling.sphere_in_frustum(planes, (1.9, 0, 0.9), 0.0)
    assert not culling.sphere_in_frustum(planes, (2.5, 0, 0), 0.4)
    assert culling.sphere_in_frustum(planes, (2.5, 0, 0), 0.6)


def test_bounding_sphere_holds_the_corners():
    corners = np.array([[x, y, z] for x in (-1, 2) for y in (0, 1) for z in (3, 5)], float)
    centre, radius = culling.bounding_sphere(corners)
    np.testing.assert_allclose(centre, (0.5, 0.5, 4))
    assert math.isclose(radius, math.sqrt(1.5 ** 2 + 0.5 ** 2 + 1))


# ---------------------------------------------------------------- layout

@pytest.mark.parametrize("name, folder", [("Sphere", "Sphere"), ("Sphere.001", "Sphere.001"),
                                          ("my car/wheel:L", "my_car_wheel_L"), ("..", "object"),
                                          ("_world", "world"), ("Ölfass", "Ölfass")])
def test_folder_names_are_portable(name, folder):
    assert layout.folder_name(name) == folder


def test_records_make_a_cache_only_with_their_maps(tmp_path):
    folder = str(tmp_path)
    assert not layout.is_cached(folder, None, "abc", ["diffuse"])
    (tmp_path / "diffuse.exr").write_bytes(b"x")
    layout.write_record(folder, None, "abc", ["diffuse"])
    assert layout.is_cached(folder, None, "abc", ["diffuse"])
    assert not layout.is_cached(folder, None, "abd", ["diffuse"])          # inputs changed
    assert not layout.is_cached(folder, None, "abc", ["diffuse", "specular"])  # a map missing
    assert not layout.is_cached(folder, 3, "abc", ["diffuse"])             # other frame
    layout.write_record(folder, 3, "h3", [])
    assert (tmp_path / "bake_0003.json").is_file()
    (tmp_path / "bake.json").write_text("{not json")
    assert not layout.is_cached(folder, None, "abc", ["diffuse"])          # unreadable: stale
    assert not [p for p in os.listdir(folder) if p.startswith(".tmp")]


def test_check_writable(tmp_path):
    layout.check_writable(str(tmp_path / "new" / "maps"))
    assert (tmp_path / "new" / "maps").is_dir()
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(PlateLightError, match="Cannot create the maps folder"):
        layout.check_writable(str(blocker / "maps"))


def test_remove_other_maps_keeps_needed_and_other_frames(tmp_path):
    for name in ("diffuse.exr", "specular.exr", "glossy1.exr", "specular_0002.exr", "notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    assert layout.remove_other_maps(str(tmp_path), None, keep=("diffuse",)) == ["glossy1", "specular"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["diffuse.exr", "notes.txt", "specular_0002.exr"]


def test_probe_reuse_measures_travel_and_turn_in_bounding_radii():
    corners = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    radius = np.sqrt(3)
    # travel: the centre's distance over the radius
    assert probe_reuse.moved(corners + (0.3, 0, 0), (0.3, 0, 0), corners, (0, 0, 0), radius) == \
        pytest.approx(0.3 / radius)
    # turn about the centroid by 20 degrees: a corner moves 2 r sin(10 degrees)
    a = np.radians(20)
    turned = corners @ np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]).T
    assert probe_reuse.moved(turned, (0, 0, 0), corners, (0, 0, 0), radius) == \
        pytest.approx(2 * np.sin(a / 2) * np.hypot(1, 1) / radius)
    # the larger of the two; surfaces that do not correspond, or no size, never reuse
    assert probe_reuse.moved(turned + (0.1, 0, 0), (0.1, 0, 0), corners, (0, 0, 0), radius) == \
        pytest.approx(2 * np.sin(a / 2) * np.hypot(1, 1) / radius)
    assert probe_reuse.moved(corners[:7], (0, 0, 0), corners, (0, 0, 0), radius) == float("inf")
    assert probe_reuse.moved(corners, (0, 0, 0), corners, (0, 0, 0), 0.0) == float("inf")
    rendered = {"points": corners, "origin": (0, 0, 0)}
    assert probe_reuse.reusable(corners + (0.2, 0, 0), (0.2, 0, 0), rendered, radius, 0.25)
    assert not probe_reuse.reusable(corners + (0.5, 0, 0), (0.5, 0, 0), rendered, radius, 0.25)
    assert not probe_reuse.reusable(corners, (0, 0, 0), rendered, radius, 0.0)      # 0: every frame
    assert not probe_reuse.reusable(corners, (0, 0, 0), None, radius, 0.25)         # nothing rendered yet
