"""`python -m platelight maps`: the design.md contract and every bad input of issue 3."""
import json
import os

import numpy as np
import OpenEXR
import pytest

import support
from platelight.addon.exr_io import read_exr, write_exr


@pytest.fixture
def probe(tmp_path):
    env = np.full((32, 64, 3), 0.5, np.float32)
    env[8, 10] = 50.0
    path = tmp_path / "probe.exr"
    write_exr(path, env)
    return path


def assert_one_clear_error(proc, *needles):
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.strip().splitlines() if line]
    assert len(lines) == 1, proc.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_maps_contract(probe, tmp_path):
    out = tmp_path / "out"
    proc = support.run_cli("maps", probe, "--out", out, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for name, h in (("diffuse", 16), ("glossy1", 32), ("glossy2", 64), ("specular", 128)):
        image = read_exr(out / f"{name}.exr")
        assert image.shape == (h, 2 * h, 3) and image.dtype == np.float32
    data = json.loads((out / "sh.json").read_text())
    assert data["lmax"] == 15
    coeffs = np.array(data["coefficients"])
    assert coeffs.shape == (256, 3)
    # The mean radiance is c00 / (2√π).
    assert coeffs[0, 0] / (2 * np.sqrt(np.pi)) == pytest.approx(0.5 + 49.5 * 0.0002, rel=0.2)
    assert not [f for f in os.listdir(out) if f.startswith(".tmp")]


def test_paper_mode_flags(probe, tmp_path):
    proc = support.run_cli("maps", probe, "--out", tmp_path / "p", "--sampling", "paper",
                           "--samples", "1024", "--seed", "3")
    assert proc.returncode == 0, proc.stderr
    data = json.loads((tmp_path / "p" / "sh.json").read_text())
    assert data["sampling"] == "paper" and data["samples"] == 1024 and data["seed"] == 3


def test_lobes_flag_blurs_the_glossy_maps_with_ggx(probe, tmp_path):
    """--lobes ggx: the glossy maps are those of MapSettings(lobes="ggx"), recorded in sh.json;
    the diffuse and specular maps are the same as with the default Phong lobes."""
    from platelight.addon.ibl import maps
    runs = {}
    for lobes in ("phong", "ggx"):
        proc = support.run_cli("maps", probe, "--out", tmp_path / lobes, "--lobes", lobes)
        assert proc.returncode == 0, proc.stderr
        assert json.loads((tmp_path / lobes / "sh.json").read_text())["lobes"] == lobes
        runs[lobes] = {n: read_exr(tmp_path / lobes / f"{n}.exr") for n in maps.MAP_NAMES}
    expected = maps.compute_maps(read_exr(probe), maps.MapSettings(lobes="ggx")).maps
    for name in maps.MAP_NAMES:
        np.testing.assert_allclose(runs["ggx"][name], expected[name], rtol=1e-5, atol=1e-6)
    for name in ("diffuse", "specular"):
        np.testing.assert_array_equal(runs["ggx"][name], runs["phong"][name])
    assert np.abs(runs["ggx"]["glossy2"] - runs["phong"]["glossy2"]).max() > 0.1
    bad = support.run_cli("maps", probe, "--out", tmp_path / "bad", "--lobes", "blinn")
    assert bad.returncode != 0 and "Traceback" not in bad.stderr


def test_missing_file(tmp_path):
    assert_one_clear_error(support.run_cli("maps", tmp_path / "nope.exr", "--out", tmp_path / "o"),
                           "File not found")


def test_not_an_exr(tmp_path):
    path = tmp_path / "fake.exr"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + b"0" * 100)
    assert_one_clear_error(support.run_cli("maps", path, "--out", tmp_path / "o"), "Not an OpenEXR")


def test_truncated_exr(probe, tmp_path):
    data = probe.read_bytes()
    path = tmp_path / "cut.exr"
    path.write_bytes(data[: len(data) // 2])
    assert_one_clear_error(support.run_cli("maps", path, "--out", tmp_path / "o"), "truncated or corrupt")


def test_wrong_aspect_ratio(tmp_path):
    path = tmp_path / "square.exr"
    write_exr(path, np.ones((32, 32, 3)))
    assert_one_clear_error(support.run_cli("maps", path, "--out", tmp_path / "o"), "twice as wide")


def test_tiny_image(tmp_path):
    path = tmp_path / "tiny.exr"
    write_exr(path, np.ones((1, 2, 3)))
    assert_one_clear_error(support.run_cli("maps", path, "--out", tmp_path / "o"), "at least")


def test_nan_inf_negative_pixels_are_repaired_with_a_warning(tmp_path):
    env = np.ones((32, 64, 3), np.float32)
    env[3, 4] = np.nan
    env[5, 6] = np.inf
    env[7, 8] = -1
    path = tmp_path / "bad.exr"
    write_exr(path, env)
    proc = support.run_cli("maps", path, "--out", tmp_path / "o")
    assert proc.returncode == 0, proc.stderr
    assert "2 pixel(s)" in proc.stderr and "NaN or infinite" in proc.stderr
    assert "1 pixel(s)" in proc.stderr and "negative" in proc.stderr
    for name in ("diffuse", "glossy1", "glossy2", "specular"):
        image = read_exr(tmp_path / "o" / f"{name}.exr")
        assert np.isfinite(image).all() and image.min() >= 0


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_output_folder_as_user(probe, tmp_path):
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o500)
    assert_one_clear_error(support.run_cli("maps", probe, "--out", out), "not writable")


def test_output_path_is_a_file(probe, tmp_path):
    target = tmp_path / "file.txt"
    target.write_text("keep me")
    assert_one_clear_error(support.run_cli("maps", probe, "--out", target), "not a folder")
    assert target.read_text() == "keep me"


def test_output_below_a_file_cannot_be_created(probe, tmp_path):
    target = tmp_path / "file.txt"
    target.write_text("keep me")
    assert_one_clear_error(support.run_cli("maps", probe, "--out", target / "sub"), "Cannot create")


def test_failed_run_leaves_earlier_maps_untouched(probe, tmp_path):
    out = tmp_path / "o"
    assert support.run_cli("maps", probe, "--out", out).returncode == 0
    before = {f: (out / f).read_bytes() for f in os.listdir(out)}
    bad = tmp_path / "square.exr"
    write_exr(bad, np.ones((8, 8, 3)))
    assert support.run_cli("maps", bad, "--out", out).returncode != 0
    assert {f: (out / f).read_bytes() for f in os.listdir(out)} == before


def test_rerun_replaces_maps_atomically(probe, tmp_path):
    out = tmp_path / "o"
    assert support.run_cli("maps", probe, "--out", out).returncode == 0
    write_exr(probe, np.full((32, 64, 3), 2.0, np.float32))
    assert support.run_cli("maps", probe, "--out", out).returncode == 0
    np.testing.assert_allclose(read_exr(out / "diffuse.exr"), 2.0, rtol=1e-4)
    assert sorted(os.listdir(out)) == ["diffuse.exr", "glossy1.exr", "glossy2.exr", "sh.json", "specular.exr"]


def test_exr_reader_formats(tmp_path):
    """RGBA, half, tiled and luminance-only inputs all read as float32 RGB."""
    rng = np.random.default_rng(0)
    rgb = rng.random((16, 32, 3)).astype(np.float32)
    half = {c: rgb[..., i].astype(np.float16) for i, c in enumerate("RGB")}
    half["A"] = np.ones((16, 32), np.float16)
    OpenEXR.File({"compression": OpenEXR.PIZ_COMPRESSION, "type": OpenEXR.scanlineimage},
                 half).write(str(tmp_path / "half_rgba.exr"))
    tiled = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    tiles = OpenEXR.TileDescription()
    tiles.xSize, tiles.ySize = 8, 8
    OpenEXR.File({"type": OpenEXR.tiledimage, "tiles": tiles}, tiled).write(str(tmp_path / "tiled.exr"))
    assert OpenEXR.File(str(tmp_path / "tiled.exr"), header_only=True).header()["type"] == OpenEXR.tiledimage
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Y": np.ascontiguousarray(rgb[..., 1])}).write(str(tmp_path / "y.exr"))
    np.testing.assert_allclose(read_exr(tmp_path / "half_rgba.exr"), rgb, atol=1e-3)
    assert read_exr(tmp_path / "half_rgba.exr", "RGBA").shape == (16, 32, 4)
    np.testing.assert_array_equal(read_exr(tmp_path / "tiled.exr"), rgb)
    np.testing.assert_array_equal(read_exr(tmp_path / "y.exr")[..., 2], rgb[..., 1])


def test_demo_maps_stage(tmp_path):
    proc = support.run_cli("demo", "--out", tmp_path / "demo", "--maps-only")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "demo" / "maps_contact_sheet.png").stat().st_size > 10_000
    for name in ("diffuse", "glossy1", "glossy2", "specular"):
        assert read_exr(tmp_path / "demo" / "maps" / f"{name}.exr").shape[1] > 0


def test_output_folder_on_a_read_only_filesystem(probe):
    """Works as root too: nobody can create folders in /proc."""
    assert_one_clear_error(support.run_cli("maps", probe, "--out", "/proc/platelight-out"),
                           "Cannot create output folder")
