"""The checkout is a valid Blender extension (Blender's own validator) and imports without bpy."""
import subprocess
import sys

import support


def test_blender_extension_validator_accepts_the_checkout():
    proc = subprocess.run([sys.executable, str(support.REPO / "tools" / "extension.py"), "validate"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Success" in proc.stdout


def test_root_package_imports_without_bpy():
    code = ("import sys; import platelight, platelight.addon.ibl.maps, platelight.cli, platelight.drivers.bake, platelight.drivers.render, platelight.drivers.demo; "
            "assert 'bpy' not in sys.modules, 'bpy imported'")
    proc = subprocess.run([sys.executable, "-c", code], env=support.cli_env(),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr


def test_cli_help_lists_subcommands():
    proc = support.run_cli("--help")
    assert proc.returncode == 0
    for name in ("maps", "demo"):
        assert name in proc.stdout


def test_venv_runs_platelight_from_any_folder(tmp_path):
    """`make` links the checkout into the project's .venv: `python -m platelight` works from any
    folder without PYTHONPATH (the README's promise)."""
    import os
    import pathlib

    import pytest

    prefix = pathlib.Path(sys.prefix)
    if prefix.parent != support.REPO or not (prefix.name == ".venv" or prefix.name.startswith(".venv-")):
        pytest.skip("not running inside this checkout's .venv or .venv-X.Y (made by `make test`)")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-m", "platelight", "--help"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "maps" in proc.stdout
