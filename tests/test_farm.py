"""Farm engine without Blender: the OpenJD template (checked by the real openjd-cli), the YAML
writer (read back by PyYAML), frame chunks, Cryptomatte hashing, progress lines."""
from __future__ import annotations

import io
import pathlib
import subprocess
import sys

import numpy as np
import pytest
import yaml

import support  # noqa: F401  (puts this checkout first on sys.path)
from platelight.addon.errors import PlateLightError
from platelight.addon.farm import jobs, multilayer, yaml_out
from platelight.addon.farm.progress import Progress

OPENJD = pathlib.Path(sys.executable).parent / "openjd"


def job(**kw):
    return jobs.FarmJob(**{"name": "PlateLight shot", "scene": "scene/shot.blend", "frames": [1, 2, 3, 4, 7],
                           "chunk": 2, **kw})


def test_yaml_reads_back_as_written():
    data = {"a": "x: y # not a comment", "b": [1, 2.5, True, {"c": "{{Param.X}}", "d": []}],
            "e": {}, "f": "line 1\nline 2\n", "g": "ünïcode \"quoted\" 'single'", "h": [[1, 2], "-"]}
    assert yaml.safe_load(yaml_out.dump(data)) == data


def test_chunks_and_range_expression():
    assert jobs.chunks([1, 2, 3, 4, 7], 2) == [[1, 2], [3, 4], [7]]
    assert jobs.chunks([5, 1, 2, 3], 10) == [[1, 2, 3], [5]]
    assert jobs.range_expression([7, 1, 2, 3, 4, 9, 10]) == "1-4,7,9-10"
    with pytest.raises(PlateLightError, match="at least 1 frame"):
        jobs.chunks([1, 2], 0)


def test_template_passes_openjd_check(tmp_path):
    written = jobs.write_bundle(str(tmp_path), job(python=sys.executable))
    assert [pathlib.Path(p).name for p in written] == ["template.yaml", "parameter_values.yaml",
                                                       "asset_references.yaml"]
    result = subprocess.run([str(OPENJD), "check", str(tmp_path / "template.yaml")], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = subprocess.run([str(OPENJD), "summary", str(tmp_path / "template.yaml"), "--output", "json"],
                             capture_output=True, text=True, timeout=120)
    assert summary.returncode == 0, summary.stderr
    template = yaml.safe_load((tmp_path / "template.yaml").read_text())
    assert template == jobs.template(job(python=sys.executable))
    names = [s["name"] for s in template["steps"]]
    assert names == [jobs.BAKE_STEP, jobs.RENDER_STEP]
    assert template["steps"][1]["dependencies"] == [{"dependsOn": jobs.BAKE_STEP}]
    defaults = {p["name"]: p["default"] for p in template["parameterDefinitions"]}
    assert defaults["SceneFile"] == "scene/shot.blend" and defaults["OutputDir"] == "output"
    assert defaults["Frames"] == "1-4,7" and defaults["ChunkSize"] == 2
    values = yaml.safe_load((tmp_path / "parameter_values.yaml").read_text())["parameterValues"]
    assert {v["name"]: v["value"] for v in values} == defaults
    refs = yaml.safe_load((tmp_path / "asset_references.yaml").read_text())["assetReferences"]
    assert refs["inputs"]["directories"] == ["scene"] and "output" in refs["outputs"]["directories"]


def test_template_without_bake_and_bad_jobs():
    template = jobs.template(job(bake=False))
    assert [s["name"] for s in template["steps"]] == [jobs.RENDER_STEP]
    assert "dependencies" not in template["steps"][0]
    with pytest.raises(PlateLightError, match="at least 1 frame"):
        jobs.template(job(chunk=0))
    with pytest.raises(PlateLightError, match="inside the bundle"):
        jobs.template(job(scene="/abs/shot.blend"))
    with pytest.raises(PlateLightError, match="inside the bundle"):
        jobs.template(job(output="../elsewhere"))


def test_commands_are_the_cli():
    """The steps run the documented CLI: every flag they pass exists in `python -m platelight`."""
    from platelight.cli import build_parser

    parser = build_parser()
    bake = parser.parse_args(jobs.bake_args("s.blend", "1-4"))
    render = parser.parse_args(jobs.render_args("s.blend", "out", "1-2", "composite", "multilayer"))
    assert bake.command == "bake" and bake.frames == "1-4" and bake.quiet
    assert render.command == "render" and render.format == "multilayer" and render.quiet


def test_murmur3_and_cryptomatte_ids():
    # reference values of MurmurHash3_x86_32, seed 0
    assert multilayer.murmur3_32(b"") == 0
    assert multilayer.murmur3_32(b"hello") == 0x248BFA47
    assert multilayer.murmur3_32(b"The quick brown fox jumps over the lazy dog") == 0x2E4FF723
    # Blender 5.2.3's own manifest and layer key, read from a render of this project's test scene
    assert multilayer.manifest_for(["Sphere", "Ground"]) == {"Sphere": "e5e9b0db", "Ground": "24950135"}
    assert multilayer.crypto_key("CryptoObject") == "3ae39a5"
    ids = np.array([multilayer.crypto_id(n) for n in ("Sphere", "Ground", "a", "bb", "Suzanne.001")])
    assert np.all(np.isfinite(ids)) and np.all(np.abs(ids[ids != 0]) > np.finfo(np.float32).tiny)


def test_holdout_is_the_phantoms_coverage():
    ground, ball = multilayer.crypto_id("Ground"), multilayer.crypto_id("Ball")
    layer0 = np.zeros((1, 3, 4), np.float32)
    layer0[0, 0] = (ground, 1.0, 0, 0)              # all ground
    layer0[0, 1] = (ball, 0.7, ground, 0.3)         # an edge: 30 % ground
    layer0[0, 2] = (ball, 1.0, 0, 0)
    layers = [layer0, np.zeros_like(layer0), np.zeros_like(layer0)]
    assert multilayer.coverage(layers, ["Ground"])[0].tolist() == pytest.approx([1.0, 0.3, 0.0])


def test_progress_line():
    out = io.StringIO()
    progress = Progress("render", 3, stream=out)
    line = progress.step("frame 7")
    assert line.startswith("platelight render: frame 7 done (1/3, 2 left), ")
    assert "per frame, about" in line and out.getvalue() == line + "\n"
    progress.step("frame 8")
    assert "left" not in progress.step("frame 9").split("per frame")[1]
