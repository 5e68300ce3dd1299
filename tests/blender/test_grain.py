"""platelight.match_grain in headless Cycles: on a grainy plate the composite's CG gets grain of
the plate's sigma (measured as the difference to the same render without grain), pixels the CG
does not touch stay exactly the plate, re-running updates in place, bad input is refused."""
import numpy as np
import pytest

import support  # noqa: F401
from support import compat
from composite_scene import add_camera, add_plane, add_sphere, add_sun, grey_world, render_with_passes
from platelight.addon.exr_io import write_exr

W, H = 192, 108
SIGMA = np.array([0.02, 0.03, 0.045])


def grainy_plate(path):
    """A smooth plate (gradient + soft blob) with white Gaussian grain of SIGMA."""
    rng = np.random.default_rng(5)
    y, x = np.mgrid[0:H, 0:W]
    base = 0.3 + 0.2 * x / W + 0.15 * np.exp(-((x - 50) ** 2 + (y - 30) ** 2) / 800.0)
    plate = base[..., None] * np.array([1.0, 0.9, 0.8]) + SIGMA * rng.standard_normal((H, W, 3))
    write_exr(path, plate.astype(np.float32))
    return plate.astype(np.float32)


def grain_scene(bpy, tmp_path):
    scene = bpy.context.scene
    plate = grainy_plate(tmp_path / "plate.exr")
    add_camera(bpy, scene)
    add_plane(bpy, scene).platelight.phantom = True
    add_sphere(bpy, scene)
    add_sun(bpy, scene)
    grey_world(bpy, scene, 0.15)
    scene.platelight.maps_dir = str(tmp_path / "maps")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    scene.frame_end = 2                      # a still plate, but grain for two frames
    assert bpy.ops.platelight.setup_composite(samples=8) == {"FINISHED"}
    return scene, plate


def test_match_grain_gives_the_cg_the_plates_grain(bpy_clean, tmp_path, capfd):
    bpy = bpy_clean
    scene, plate = grain_scene(bpy, tmp_path)
    tree = compat().compositor_tree(scene)
    diff = tree.nodes["PlateLight Differential"]
    clean, clean_passes = render_with_passes(bpy, scene, tmp_path / "clean")
    assert bpy.ops.platelight.match_grain() == {"FINISHED"}
    report = "".join(capfd.readouterr())
    assert "Grain matched: sigma" in report
    files = sorted(p.name for p in (tmp_path / "maps" / "grain").iterdir())
    assert files == ["grain_0001.exr", "grain_0002.exr"]
    assert diff.inputs["Grain Amount"].default_value == 1.0
    assert diff.inputs["Grain"].links[0].from_node.image.name == "PlateLight Grain"
    grained, passes = render_with_passes(bpy, scene, tmp_path / "grained")

    alpha = passes["CG"][..., 3]
    inside = alpha == 1.0
    assert inside.sum() > 300
    added = (grained - clean)[..., :3][inside]         # the same render: only the grain differs
    # the plate's grain is the same at every level here: the CG gets that sigma (to 10 %)
    np.testing.assert_allclose(added.std(axis=0), SIGMA, rtol=0.10)
    assert np.all(np.abs(added.mean(axis=0)) < 0.2 * SIGMA)
    # pixels the CG does not reach: exactly as without grain, and exactly the plate where the
    # render says untouched
    outside = alpha == 0
    np.testing.assert_array_equal(grained[outside], clean[outside])
    free = outside & np.all(passes["Shadows"][..., :3] == 1, axis=2)
    assert free.mean() > 0.5
    assert np.abs(grained[..., :3] - plate)[free].max() <= 1e-6

    # frame 2 gets other grain; re-running updates in place; setup_composite keeps it wired
    scene.frame_set(2)
    second, _ = render_with_passes(bpy, scene, tmp_path / "second")
    other = (second - clean)[..., :3][inside]
    assert abs(np.corrcoef(other[:, 1], added[:, 1])[0, 1]) < 0.2
    assert bpy.ops.platelight.match_grain(seed=3) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(samples=8) == {"FINISHED"}
    tree = compat().compositor_tree(scene)
    assert [i.name for i in bpy.data.images if i.name.startswith("PlateLight Grain")] == ["PlateLight Grain"]
    assert [n.name for n in tree.nodes if n.name.startswith("PlateLight Grain")] == ["PlateLight Grain"]
    assert tree.nodes["PlateLight Differential"].inputs["Grain"].is_linked


def test_match_grain_without_composite_or_plate_is_refused(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = bpy.context.scene
    add_camera(bpy, scene)
    add_sphere(bpy, scene)
    before = (sorted(i.name for i in bpy.data.images), compat().compositor_tree(scene))
    with pytest.raises(RuntimeError, match="no PlateLight composite"):
        bpy.ops.platelight.match_grain()
    grainy_plate(tmp_path / "plate.exr")
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="no PlateLight composite"):
        bpy.ops.platelight.match_grain()
    assert bpy.ops.platelight.setup_composite(samples=1) == {"FINISHED"}
    bpy.data.images.remove(bpy.data.images["PlateLight Plate"])
    tree = compat().compositor_tree(scene)
    nodes = sorted(n.name for n in tree.nodes)
    with pytest.raises(RuntimeError, match="No plate found"):
        bpy.ops.platelight.match_grain()
    assert sorted(n.name for n in tree.nodes) == nodes
    assert "PlateLight Grain" not in bpy.data.images
    assert before[0] == []
