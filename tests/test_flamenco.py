"""The Flamenco 3 job type (addon/farm/flamenco/platelight_composite.js), run by node with
stand-ins for the Manager's job compiler API (tests/flamenco_harness.js; its frameChunker is a
port of the Manager's): it parses, bakes first, and its commands are the CLI's own (the same
argument lists as the OpenJD bundle's, accepted by `python -m platelight`'s parser). A Flamenco
Manager and Worker were not run (docs/farm.md)."""
from __future__ import annotations

import json
import pathlib
import shutil
import subprocess

import pytest

import support
from platelight.addon.bake.frames import parse_frames
from platelight.cli import build_parser
from platelight.addon.farm import jobs

SCRIPT = support.REPO / "addon" / "farm" / "flamenco" / "platelight_composite.js"
HARNESS = pathlib.Path(__file__).parent / "flamenco_harness.js"
NODE = shutil.which("node")
pytestmark = pytest.mark.skipif(NODE is None, reason="node (to run the Flamenco job type) is not installed")


def compile_job(tmp_path, **settings):
    settings = {"frames": "1-10, 15", "chunk_size": 4, "render_output_root": "/farm/out",
                "output_name": "composite", "output_format": "multilayer", "platelight_python": "/opt/pl/python",
                "blendfile": "/farm/shot/scene.blend", **settings}
    (tmp_path / "settings.json").write_text(json.dumps(settings))
    result = subprocess.run([NODE, str(HARNESS), str(SCRIPT), str(tmp_path / "settings.json")],
                            capture_output=True, text=True, timeout=60)
    return result, settings


def test_script_parses():
    result = subprocess.run([NODE, "--check", str(SCRIPT)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


def test_bake_then_chunked_renders_with_the_cli_commands(tmp_path):
    result, settings = compile_job(tmp_path)
    assert result.returncode == 0, result.stderr
    authored = json.loads(result.stdout)
    assert authored["label"] == "PlateLight Composite"
    bake, *renders = authored["tasks"]
    assert bake["name"] == "bake-probes" and bake["dependencies"] == []
    (command,) = bake["commands"]
    assert command["type"] == "exec" and command["parameters"]["exe"] == "/opt/pl/python"
    assert command["parameters"]["args"] == ["-m", "platelight", *jobs.bake_args(settings["blendfile"], "1-10,15")]
    parser = build_parser()
    covered = []
    for task in renders:
        assert task["dependencies"] == ["bake-probes"] and task["type"] == "misc"
        (command,) = task["commands"]
        args = command["parameters"]["args"]
        assert args[:2] == ["-m", "platelight"]
        chunk = args[args.index("--frames") + 1]
        assert args[2:] == jobs.render_args(settings["blendfile"], "/farm/out", chunk, "composite", "multilayer")
        parsed = parser.parse_args(args[2:])
        assert parsed.command == "render" and parsed.quiet
        frames = parse_frames(parsed.frames)
        assert len(frames) <= 4
        covered += frames
    assert covered == list(range(1, 11)) + [15]
    assert [t["name"] for t in renders] == ["render-1-4", "render-5-8", "render-9,10,15"]


def test_bad_chunk_size_is_refused(tmp_path):
    result, _ = compile_job(tmp_path, chunk_size=0)
    assert result.returncode != 0 and "The chunk size must be at least 1 frame, not 0." in result.stderr
