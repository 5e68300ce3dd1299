"""The AR demo end to end, at a tiny size: every output is written, the composite differs from
the plate where the CG is and equals it far from it, and the stage timings are reported."""
import json

import numpy as np

import support  # noqa: F401
from support import compat
from platelight.drivers.demo_ar import run_ar_demo
from platelight.addon.exr_io import read_exr


def test_ar_demo_small(bpy_clean, tmp_path):
    timings = run_ar_demo(tmp_path, frames=2, size=(96, 54))
    for name in ("film_plate_s", "setup_s", "render_composite_s", "contact_sheet_s", "total_s"):
        assert timings[name] >= 0
    assert json.loads((tmp_path / "timings.json").read_text())["frames"] == 2
    assert (tmp_path / "contact_sheet.png").stat().st_size > 1000
    for frame in (1, 2):
        assert (tmp_path / "composite" / f"composite_{frame:04d}.png").exists()
        plate = read_exr(tmp_path / "plate" / f"plate_{frame:04d}.exr")
        comp = read_exr(tmp_path / "composite" / f"composite_{frame:04d}.exr")
        passes = str(tmp_path / "passes" / f"{frame:04d}")
        cg = read_exr(compat().file_output_path(passes, "CG", frame), "RGBA")
        shadows = read_exr(compat().file_output_path(passes, "Shadows", frame))
        on_cg = cg[..., 3] > 0.99
        assert on_cg.mean() > 0.03                          # the CG objects are in view
        assert np.abs(comp - plate)[on_cg].mean() > 0.02     # and change the picture there
        assert (shadows[..., 1] < 0.8).sum() > 10            # they cast shadows on the floor
        # SBRDF objects shine their probe light onto the floor (an emission closure), so light
        # from the CG reaches much of the floor: what it does not reach must be exact
        untouched = (cg[..., 3] == 0) & np.all(shadows == 1, axis=2)
        assert untouched.mean() > 0.1
        assert np.abs(comp - plate)[untouched].max() <= 1e-6
    assert not list(tmp_path.rglob("*.partial*"))
