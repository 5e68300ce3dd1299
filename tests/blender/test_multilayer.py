"""`python -m platelight render --format multilayer`: one EXR per frame whose layers OpenEXR lists
by name, whose composite is bit-identical to the plain EXR render, whose passes equal the
single-pass files Blender writes for the same frame, which Blender's compositor opens as
separate passes, and which leaves the plate's files untouched."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import OpenEXR
import pytest

import support
from farm_scene import make_shot
from platelight.addon.exr_io import read_exr
from platelight.addon.farm import multilayer

CHANNELS = {"R", "G", "B", "A", "CG.R", "CG.G", "CG.B", "CG.A", "Shadows.R", "Shadows.G", "Shadows.B",
            "Holdout.A", "Depth.Z", "Normal.X", "Normal.Y", "Normal.Z",
            *(f"CryptoObject{k:02d}.{c}" for k in range(3) for c in "RGBA")}


@pytest.fixture
def rendered(bpy_clean, tmp_path):
    blend, plates = make_shot(bpy_clean, tmp_path)
    plate_files = sorted((tmp_path / "plate").iterdir())
    before = [hashlib.sha256(p.read_bytes()).hexdigest() for p in plate_files]
    assert support.run_cli("bake", blend, "--frames", "1-2").returncode == 0
    for fmt in ("exr", "multilayer"):
        result = support.run_cli("render", blend, "--frames", "1-2", "--out", tmp_path / fmt, "--format", fmt)
        assert result.returncode == 0, result.stderr[-2000:]
    assert [hashlib.sha256(p.read_bytes()).hexdigest() for p in plate_files] == before
    return blend, tmp_path


def test_layers_and_composite(rendered):
    _, root = rendered
    path = root / "multilayer" / "composite_0001.exr"
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        names = set(exr.channels())
        assert all(c.pixels.dtype == np.float32 for c in exr.channels().values())
        header = dict(exr.header())
    assert names == CHANNELS
    layers = multilayer.read_layers(str(path))
    assert np.array_equal(layers[""], read_exr(root / "exr" / "composite_0001.exr", "RGBA"))
    key = multilayer.crypto_key("CryptoObject")
    assert header[f"cryptomatte/{key}/name"] == "CryptoObject"
    manifest = json.loads(header[f"cryptomatte/{key}/manifest"])
    assert manifest["Ball"] == f"{multilayer.murmur3_32(b'Ball'):08x}" and "Ground" in manifest
    # ids in the pixels are the manifest's objects; the ground's coverage is the holdout matte
    ids = set(np.unique(layers["CryptoObject00"][..., 0]).tolist()) - {0.0}
    assert ids <= {float(multilayer.crypto_id(n)) for n in manifest}
    holdout = layers["Holdout"][..., 0]
    assert np.array_equal(holdout, multilayer.coverage([layers[f"CryptoObject{k:02d}"] for k in range(3)], ["Ground"]))
    assert holdout.min() == 0.0 and holdout.max() == pytest.approx(1.0, abs=1e-6) and 0.2 < holdout.mean() < 0.8
    cg_alpha = layers["CG"][..., 3]
    assert cg_alpha.max() > 0.99 and (cg_alpha == 0).mean() > 0.5       # the ball, premultiplied alpha
    shadows = layers["Shadows"]
    assert shadows.min() < 0.9 and np.median(shadows) == pytest.approx(1.0, abs=1e-6)   # its shadow on the ground
    # depth along the view axis of the level camera 1.5 m above the ground (farm_scene): a ground
    # pixel whose ray drops by t per unit of depth is 1.5 / t away (within the pixel's footprint)
    ground = (holdout > 0.99) & (cg_alpha == 0)
    height, width = holdout.shape
    rows = np.nonzero(ground)[0]
    t = ((rows + 0.5) - height / 2) / width * (36.0 / 50.0)      # 50 mm lens, 36 mm sensor width
    assert ground.sum() > 100 and np.allclose(layers["Depth"][..., 0][ground] * t, 1.5, rtol=0.08)
    normal = layers["Normal"]
    assert np.allclose(normal[ground], [0, 0, 1], atol=1e-4)             # the ground faces up


def test_passes_equal_blenders_single_pass_files(rendered, bpy_module, tmp_path):
    """The same frame rendered in this process with the pass files node writing single EXRs."""
    from bl_ext.dev.platelight.node_groups import passes

    bpy = bpy_module
    blend, root = rendered
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    scene.render.use_persistent_data = True
    passes.wire_pass_files(scene, str(tmp_path / "single") + "/")
    scene.frame_set(1)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "single_composite.exr")
    bpy.ops.render.render(write_still=True)
    layers = multilayer.read_layers(str(root / "multilayer" / "composite_0001.exr"))
    for stem in passes.PASS_FILES:
        single, _ = multilayer._read_any(support.compat().file_output_path(str(tmp_path / "single"), stem, 1))
        width = {"Shadows": 3, "Depth": 1, "Normal": 3}.get(stem, 4)
        assert np.array_equal(layers[stem], single[..., :width]), stem


def test_blender_reads_the_layers_as_passes(rendered, bpy_module):
    bpy = bpy_module
    _, root = rendered
    image = bpy.data.images.load(str(root / "multilayer" / "composite_0002.exr"))
    tree = bpy.data.node_groups.new("Read Multilayer", "CompositorNodeTree")
    try:
        node = tree.nodes.new("CompositorNodeImage")
        node.image = image
        outputs = {s.name for s in node.outputs if s.enabled}
    finally:
        bpy.data.node_groups.remove(tree)
        bpy.data.images.remove(image)
    assert {"Combined", "CG", "Shadows", "Holdout", "Depth", "Normal",
            "CryptoObject00", "CryptoObject01", "CryptoObject02"} <= outputs, outputs
