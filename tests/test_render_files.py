"""The file logic of `python -m platelight render` (no Blender): what counts as a complete frame,
temporary names that never look like frames, and the resume plan."""
import glob
import os

import numpy as np

import support  # noqa: F401
from platelight.addon import fileio, render_files
from platelight.addon.exr_io import write_exr


def png(path, rgb8):
    import cv2

    assert cv2.imwrite(str(path), rgb8)


def test_truncated_exr_and_png_are_incomplete(tmp_path):
    write_exr(tmp_path / "a.exr", np.random.default_rng(0).random((40, 60, 4)).astype(np.float32))
    png(tmp_path / "a.png", np.random.default_rng(1).integers(0, 256, (40, 60, 3), dtype=np.uint8))
    for name in ("a.exr", "a.png"):
        path = tmp_path / name
        assert render_files.is_complete(str(path))
        data = path.read_bytes()
        for cut in (0, 10, len(data) // 2, len(data) - 1):
            path.write_bytes(data[:cut])
            assert not render_files.is_complete(str(path)), (name, cut)
    assert not render_files.is_complete(str(tmp_path / "missing.exr"))


def test_temporary_names_are_hidden_and_found_again(tmp_path):
    final = render_files.frame_path(str(tmp_path), "composite", 7, ".exr")
    assert os.path.basename(final) == "composite_0007.exr"
    tmp = fileio.temp_path(final)
    assert os.path.dirname(tmp) == str(tmp_path) and tmp.endswith(".exr")
    assert os.path.basename(tmp).startswith(".composite_0007")
    open(tmp, "wb").close()
    open(fileio.temp_path(render_files.frame_path(str(tmp_path), "composite", 8, ".exr")), "wb").close()
    assert glob.glob(str(tmp_path / "composite_*.exr")) == []
    assert fileio.stale_temps(final) == [tmp]


def test_plan_keeps_complete_frames_and_redoes_broken_ones(tmp_path):
    image = np.zeros((4, 8, 4), np.float32)
    for frame in (1, 2, 4):
        write_exr(render_files.frame_path(str(tmp_path), "c", frame, ".exr"), image)
    broken = tmp_path / "c_0004.exr"
    broken.write_bytes(broken.read_bytes()[:100])
    assert render_files.plan(str(tmp_path), "c", [1, 2, 3, 4], ".exr") == ([3, 4], [1, 2], [4])
    assert render_files.plan(str(tmp_path), "c", [1, 2, 3, 4], ".exr", force=True) == ([1, 2, 3, 4], [], [4])
