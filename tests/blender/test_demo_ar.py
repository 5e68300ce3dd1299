"""The demo end to end as `python -m platelight demo` runs it, at a tiny size: the default method
takes the baked shadows, every output is written (composites, contact sheet, the comparison with
the path-traced truth and its PSNR, timings), the composite differs from the plate where the CG
is and equals it far from it, and the terminal gets stages and seconds, Blender's lines the log."""
import argparse
import json

import numpy as np

import support  # noqa: F401
from support import compat
from platelight.drivers import demo
from platelight.addon.exr_io import read_exr


def test_demo_shows_the_default_route_beside_the_truth_and_keeps_blender_in_its_log(bpy_clean, tmp_path, capfd):
    args = argparse.Namespace(out=str(tmp_path), hdri="sunset", maps_only=False, frames=2, size="96x54")
    assert demo.run(args) == 0
    said = capfd.readouterr()
    terminal = said.out + said.err
    for blender_line in ("Saved:", "Fra:", "EGL", "Warning:", "Info:"):
        assert blender_line not in terminal, blender_line
    assert "render 2 composites (baked shadows)" in terminal and "against the path-traced truth" in terminal
    log = (tmp_path / "blender.log").read_text()
    assert "Saved:" in log and "Composite set up (baked, cycles)" in log

    ar = tmp_path / "ar"
    summary = json.loads((ar / "timings.json").read_text())
    assert summary["method"] == "BAKED" and summary["frames"] == 2 and summary["size"] == [96, 54]
    for stage in ("film_plate_s", "truth_s", "bake_probes_s", "bake_shadows_s", "render_composite_s", "total_s"):
        assert summary["timings"][stage] > 0, stage
    truth = summary["truth"]
    # the composite is far closer to the truth than the bare plate (at 640x360: 42 dB against 19)
    assert truth["frame_db"] > truth["plate_alone_db"] + 6, truth
    assert truth["object_pixels"] > 50 and truth["shadow_pixels"] > 10, truth
    for sheet in ("contact_sheet.png", "truth_comparison.png"):
        assert (ar / sheet).stat().st_size > 1000
    for frame in (1, 2):
        assert (ar / "composite" / f"composite_{frame:04d}.png").exists()
        plate = read_exr(ar / "plate" / f"plate_{frame:04d}.exr")
        comp = read_exr(ar / "composite" / f"composite_{frame:04d}.exr")
        passes = str(ar / "passes" / f"{frame:04d}")
        cg = read_exr(compat().file_output_path(passes, "CG", frame), "RGBA")
        shadows = read_exr(compat().file_output_path(passes, "Shadows", frame))
        on_cg = cg[..., 3] > 0.99
        assert on_cg.mean() > 0.03                          # the CG objects are in view
        assert np.abs(comp - plate)[on_cg].mean() > 0.02     # and change the picture there
        assert (shadows[..., 1] < 0.8).sum() > 10            # they cast shadows on the floor
        untouched = (cg[..., 3] == 0) & np.all(shadows == 1, axis=2)
        assert untouched.mean() > 0.05                      # the sky and the far floor
        assert np.abs(comp - plate)[untouched].max() <= 1e-6
    assert not list(tmp_path.rglob("*.partial*"))
