"""Built node groups kept on disk between Blender runs, so a large group is built once per machine
and Blender release, not in every Blender session (probe_maps.py: a probe group with the layer behind's
look-ups has about 1400 nodes and takes 10-30 s to build, since Blender re-runs its update of
the whole tree for every node added; appending it from a .blend takes a fraction of a second).

A cached group is named by the group's name, the Blender release and a digest of the add-on's
node and engine sources, so any change to how groups are built (or to a constant they hold)
misses the cache. Any failure to read or write it falls back to building; the cache is only a
speed-up."""
from __future__ import annotations

import hashlib
import os
import pathlib
import tempfile

import bpy

_PACKAGE_ROOT = pathlib.Path(__file__).resolve().parents[1]
_SOURCES = ("node_groups", "addon")
_digest = None


def _sources_digest() -> str:
    global _digest
    if _digest is None:
        h = hashlib.sha256()
        for folder in _SOURCES:
            for path in sorted((_PACKAGE_ROOT / folder).rglob("*.py")):
                h.update(path.relative_to(_PACKAGE_ROOT).as_posix().encode())
                h.update(path.read_bytes())
        _digest = h.hexdigest()[:16]
    return _digest


def _folder() -> str:
    package = __package__.rsplit(".", 1)[0]
    try:
        return bpy.utils.extension_path_user(package, path="node_groups", create=True)
    except (ValueError, AttributeError, OSError):      # not installed as an extension
        folder = os.path.join(tempfile.gettempdir(), "platelight-node-groups")
        os.makedirs(folder, exist_ok=True)
        return folder


def _path(name: str) -> str:
    version = "-".join(str(v) for v in bpy.app.version)
    stem = "".join(c if c.isalnum() else "_" for c in name)
    return os.path.join(_folder(), f"{stem}-{version}-{_sources_digest()}.blend")


def load(name: str):
    """The group ``name`` appended from the cache, or None when it is not there."""
    try:
        path = _path(name)
        if not os.path.isfile(path):
            return None
        try:
            with bpy.data.libraries.load(path, link=False) as (source, target):
                target.node_groups = [name] if name in source.node_groups else []
        finally:
            # Reading the file leaves it behind as a library: drop it, or a saved .blend would name it
            for library in [lib for lib in bpy.data.libraries
                            if os.path.normpath(bpy.path.abspath(lib.filepath)) == os.path.normpath(path)]:
                bpy.data.libraries.remove(library)
        group = target.node_groups[0] if target.node_groups else None
        return group if group is not None and group.library is None and group.name == name else None
    except (OSError, RuntimeError, ValueError, ReferenceError):
        return None


def save(group) -> None:
    """Write ``group`` to the cache (atomically: a farm's processes may race); failures are
    ignored."""
    try:
        path = _path(group.name)
        partial = f"{path}.{os.getpid()}.partial.blend"
        bpy.data.libraries.write(partial, {group}, fake_user=False)
        os.replace(partial, path)
    except (OSError, RuntimeError, ValueError, TypeError):
        pass
