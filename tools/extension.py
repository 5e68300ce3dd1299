"""Validate or build the PlateLight extension with Blender's own extension builder (shipped in
the bpy wheel). `build` stages a copy of the package, puts the OpenEXR and OpenCV wheels for each
platform and each supported Blender's Python into it (downloaded once into wheels/), lists them
in the staged manifest and builds one zip per platform (--split-platforms). The checkout's
manifest lists no wheels, so it validates without network."""
from __future__ import annotations

import argparse
import glob
import pathlib
import re
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
REQUIREMENTS = ROOT / "requirements"
# Wheels the extension carries (numpy ships with Blender itself); their pins come from the
# requirements of the Blender releases the suite runs on, which must agree on them.
BUNDLED = ("OpenEXR", "opencv-contrib-python-headless")
WHEEL_CACHE = ROOT / "wheels"          # downloaded once, reused by later builds (gitignored)
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


def releases() -> dict[str, list[pathlib.Path]]:
    """{Python X.Y: requirement files} of each Blender release (requirements/blender-X.Y.txt and
    its -no-deps.txt); the Python is the one its first line says its bpy is built for."""
    found: dict[str, list[pathlib.Path]] = {}
    for path in sorted(REQUIREMENTS.glob("blender-*.txt")):
        if not re.fullmatch(r"blender-\d+\.\d+\.txt", path.name):
            continue
        match = re.search(r"built for Python (\d+\.\d+)", path.read_text().splitlines()[0])
        if not match:
            sys.exit(f"{path}: the first line must say which Python its bpy is built for")
        extra = path.with_name(path.stem + "-no-deps.txt")
        found.setdefault(match.group(1), []).extend([path] + ([extra] if extra.exists() else []))
    return found


def bundled_pins(files) -> dict[str, str]:
    """{package: version} of the bundled packages, the same in every release's requirements."""
    pins: dict[str, set[str]] = {name: set() for name in BUNDLED}
    for path in files:
        for line in path.read_text().splitlines():
            name, _, version = line.split("#")[0].strip().partition("==")
            if name in pins:
                pins[name].add(version)
    for name, versions in pins.items():
        if len(versions) != 1:
            sys.exit(f"{name}: the requirements pin {sorted(versions) or 'no version'}; the extension "
                     "carries one, so every release must pin the same")
    return {name: versions.pop() for name, versions in pins.items()}


def _normalised(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def fetch_wheel(name, version, python, platform, tags) -> pathlib.Path:
    """The wheel of name==version for CPython ``python`` on ``platform``, from the cache or PyPI."""
    cache = WHEEL_CACHE / platform
    cache.mkdir(parents=True, exist_ok=True)
    tag = "cp" + python.replace(".", "")

    def cached():
        for wheel in sorted(cache.glob(f"{_normalised(name)}-{version}-*.whl")):
            python_tag, abi_tag = wheel.name.split("-")[2:4]
            if tag in python_tag.split(".") or abi_tag == "abi3":
                return wheel
        return None

    if cached() is None:
        cmd = ["-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--python-version", python,
               "--implementation", "cp", "-d", cache, f"{name}=={version}"]
        for platform_tag in tags:
            cmd += ["--platform", platform_tag]
        run(*cmd)
    wheel = cached()
    if wheel is None:
        sys.exit(f"no {name} {version} wheel for Python {python} on {platform}")
    return wheel


def build(out: pathlib.Path, platforms=tuple(PLATFORMS)) -> None:
    stage = ROOT / "build" / "stage" / "platelight"
    if stage.exists():
        shutil.rmtree(stage)
    ignore = shutil.ignore_patterns(".venv*", ".git", "build", "dist", "out", "bench_out", "tests",
                                    "docs", "tools", "__pycache__", "*.pyc", "wheels", "requirements")
    shutil.copytree(ROOT, stage, ignore=ignore, symlinks=False)
    wheel_dir = stage / "wheels"
    wheel_dir.mkdir()
    found = releases()
    pins = bundled_pins([f for files in found.values() for f in files])
    # One wheel per Python where a package is built per Python (OpenEXR: cp311 and cp313), one in
    # all for a stable-ABI (abi3) wheel such as OpenCV's.
    for platform in platforms:
        for python in sorted(found):
            for name, version in pins.items():
                wheel = fetch_wheel(name, version, python, platform, PLATFORMS[platform])
                shutil.copy2(wheel, wheel_dir / wheel.name)
    wheels = sorted(f"./wheels/{p.name}" for p in wheel_dir.glob("*.whl"))
    manifest = (stage / "blender_manifest.toml").read_text()
    listing = "wheels = [\n" + "".join(f'  "{w}",\n' for w in wheels) + "]\n"
    listed = 'platforms = ["' + '", "'.join(platforms) + '"]\n'
    manifest = re.sub(r"(license = .*\n)", r"\1\n" + listed + listing, manifest, count=1)
    (stage / "blender_manifest.toml").write_text(manifest)
    validate(stage)
    out.mkdir(parents=True, exist_ok=True)
    run(blender_ext(), "build", "--source-dir", stage, "--output-dir", out, "--split-platforms")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("command", choices=("validate", "build"))
    parser.add_argument("--out", default=str(ROOT / "dist"))
    parser.add_argument("--platform", action="append", choices=tuple(PLATFORMS),
                        help="build only for this platform (repeatable; default: all)")
    args = parser.parse_args()
    if args.command == "validate":
        validate(ROOT)
    else:
        build(pathlib.Path(args.out).resolve(), tuple(args.platform or PLATFORMS))


if __name__ == "__main__":
    main()
