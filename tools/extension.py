"""Validate or build the PlateLight extension with Blender's own extension builder (shipped in
the bpy wheel). `build` stages a copy of the package, downloads the OpenEXR and OpenCV wheels
for each platform into it, lists them in the staged manifest and builds one zip per platform
(--split-platforms). The checkout's manifest lists no wheels, so it validates without network."""
from __future__ import annotations

import argparse
import glob
import pathlib
import re
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
WHEELS = {  # pinned like requirements.txt; numpy ships with Blender itself
    "OpenEXR": "3.5.3",
    "opencv-contrib-python-headless": "4.11.0.86",
}
PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux2014_x86_64", "manylinux_2_17_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_11_0_arm64", "macosx_13_0_arm64"],
}


def blender_ext() -> str:
    import sysconfig

    hits = glob.glob(str(pathlib.Path(sysconfig.get_paths()["purelib"]) / "bpy" / "*" / "scripts" /
                         "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"))
    if not hits:
        sys.exit("blender_ext.py not found inside the bpy wheel")
    return hits[0]


def run(*args) -> None:
    print("+", " ".join(map(str, args)), flush=True)
    subprocess.run([sys.executable, *map(str, args)], check=True)


def validate(source: pathlib.Path) -> None:
    run(blender_ext(), "validate", source)


def build(out: pathlib.Path) -> None:
    stage = ROOT / "build" / "stage" / "platelight"
    if stage.exists():
        shutil.rmtree(stage)
    ignore = shutil.ignore_patterns(".venv", ".git", "build", "dist", "out", "bench_out", "tests",
                                    "docs", "tools", "__pycache__", "*.pyc", "wheels")
    shutil.copytree(ROOT, stage, ignore=ignore, symlinks=False)
    wheel_dir = stage / "wheels"
    wheel_dir.mkdir()
    for platform, tags in PLATFORMS.items():
        for name, version in WHEELS.items():
            cmd = ["-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--python-version",
                   "3.11", "--implementation", "cp", "-d", wheel_dir, f"{name}=={version}"]
            for tag in tags:
                cmd += ["--platform", tag]
            run(*cmd)
    wheels = sorted(f"./wheels/{p.name}" for p in wheel_dir.glob("*.whl"))
    manifest = (stage / "blender_manifest.toml").read_text()
    listing = "wheels = [\n" + "".join(f'  "{w}",\n' for w in wheels) + "]\n"
    platforms = 'platforms = ["' + '", "'.join(PLATFORMS) + '"]\n'
    manifest = re.sub(r"(license = .*\n)", r"\1\n" + platforms + listing, manifest, count=1)
    (stage / "blender_manifest.toml").write_text(manifest)
    validate(stage)
    out.mkdir(parents=True, exist_ok=True)
    run(blender_ext(), "build", "--source-dir", stage, "--output-dir", out, "--split-platforms")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("command", choices=("validate", "build"))
    parser.add_argument("--out", default=str(ROOT / "dist"))
    args = parser.parse_args()
    if args.command == "validate":
        validate(ROOT)
    else:
        build(pathlib.Path(args.out).resolve())


if __name__ == "__main__":
    main()
