"""Where baked maps live: one folder per object under the scene's maps folder (the world's maps
in ``_world``), plus one small JSON record per baked frame holding the content hash it was baked
from."""
from __future__ import annotations

import json
import os
import re
import shutil
import tempfile

from ..errors import PlateLightError
from ..fileio import write_json_atomic
from ..ibl.distance import behind_filenames, distance_filename
from ..ibl.irradiance_grid import grid_filename
from ..ibl.maps import MAP_NAMES, map_filename
from ..ibl.sun_lobe import SUNLESS_MAPS, sunless_filename
from ..ibl.view_lobe import ladder_filenames

WORLD_FOLDER = "_world"
DEFAULT_MAPS_DIR = "//platelight_maps"   # next to the .blend (scene.platelight.maps_dir's default)
_UNSAFE = re.compile(r"[^\w.-]+")


def folder_name(object_name: str) -> str:
    """A portable folder name for an object: anything but letters, digits, '.', '-' and '_'
    becomes '_' (path separators, Windows' reserved characters, spaces for shells),
    and it never starts with '.' or '_' (the world's folder and hidden files)."""
    name = _UNSAFE.sub("_", object_name).strip("._ ") or "object"
    return name[:100]


def object_maps_dir(maps_dir: str, object_name: str) -> str:
    """The folder a bake writes an object's maps to (Blender path, '/'-terminated), also where a
    material looks for them before the object records a bake (farm bakes without --save)."""
    return (maps_dir or DEFAULT_MAPS_DIR).rstrip("/\\") + "/" + folder_name(object_name) + "/"


def record_filename(frame: int | None) -> str:
    """One small JSON record per baked frame (``bake.json``, ``bake_0010.json``): machines that
    bake different frames into the same folder never write the same file."""
    return "bake.json" if frame is None else f"bake_{int(frame):04d}.json"


def lookup_filenames(frame: int | None) -> list[str]:
    """The files of a frame that the probe group reads beside the four maps: the parallax
    look-ups' distance map and irradiance grid, the sunless maps and the view-dependent ladder's
    rungs (each present only when the bake wanted it)."""
    return ([distance_filename(frame), grid_filename(frame)] + [sunless_filename(n, frame) for n in SUNLESS_MAPS]
            + ladder_filenames(frame) + behind_filenames(frame))


def read_record(folder: str, frame: int | None) -> dict:
    """The frame's bake record, or {} if missing or unreadable (which reads as a stale cache)."""
    try:
        with open(os.path.join(folder, record_filename(frame))) as fh:
            data = json.load(fh)
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def is_cached(folder: str, frame: int | None, digest: str, maps, record: dict | None = None) -> bool:
    """True when the folder holds maps of this frame baked from inputs with this hash (``record``:
    the frame's record, where the caller has read it already)."""
    if (read_record(folder, frame) if record is None else record).get("hash") != digest:
        return False
    return all(os.path.isfile(os.path.join(folder, map_filename(n, frame))) for n in maps)


def write_record(folder: str, frame: int | None, digest: str, maps, **extra) -> None:
    """Atomically write the frame's record (after its maps, so a record always means maps)."""
    try:
        write_json_atomic(os.path.join(folder, record_filename(frame)),
                          {"hash": digest, "maps": list(maps), **extra})
    except PlateLightError:
        raise PlateLightError(f"Cannot write the bake record in {folder}.") from None


def copy_frame(folder: str, source: int, frame: int) -> list[str]:
    """Give ``frame`` the maps and look-up files of ``source`` (a probe reused for a frame in which
    its object moved little, probe_reuse.py): each copied whole (a copy, not a link: a later bake
    of either frame rewrites its file in place), and a file of ``frame`` that ``source`` lacks
    deleted, so no stale look-up is read with the copied maps. Returns the files written."""
    written = []
    for src, dst in zip([map_filename(n, source) for n in MAP_NAMES] + lookup_filenames(source),
                        [map_filename(n, frame) for n in MAP_NAMES] + lookup_filenames(frame)):
        src, dst = os.path.join(folder, src), os.path.join(folder, dst)
        if os.path.isfile(src):
            tmp = dst + ".part"
            shutil.copyfile(src, tmp)
            os.replace(tmp, dst)
            written.append(os.path.basename(dst))
        elif os.path.isfile(dst):
            os.unlink(dst)
    return written


def remove_other_maps(folder: str, frame: int | None, keep) -> list[str]:
    """Delete this frame's maps that the object no longer needs (a matte object that used to be
    glossy), so no stale map is ever picked up. Returns the names removed."""
    removed = []
    for name in MAP_NAMES:
        path = os.path.join(folder, map_filename(name, frame))
        if name not in keep and os.path.isfile(path):
            os.unlink(path)
            removed.append(name)
    return removed          # (the sunless maps are sun_lobe.bake_sunless's to write and remove)


def remove_single_frame(folder: str) -> list[str]:
    """A frame-range bake supersedes a single-frame one in the same folder: delete its
    ``diffuse.exr``... and ``bake.json``, or the binding (which prefers single files) would keep
    showing the old static maps instead of the new sequence. Returns the files removed."""
    removed = []
    single = [map_filename(n, None) for n in MAP_NAMES] + lookup_filenames(None) + [record_filename(None)]
    for filename in single:
        path = os.path.join(folder, filename)
        if os.path.isfile(path):
            os.unlink(path)
            removed.append(filename)
    return removed


def check_writable(folder: str) -> None:
    """Create ``folder`` if needed and make sure files can be written there (one sentence if not)."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise PlateLightError(f"Cannot create the maps folder {folder}: {exc.strerror}.") from None
    try:
        fd, tmp = tempfile.mkstemp(prefix=".probe-", dir=folder)
        os.close(fd)
        os.unlink(tmp)
    except OSError:
        raise PlateLightError(f"The maps folder {folder} is not writable; choose another {{maps_folder}}.",
                              maps_folder="in the scene's PlateLight settings") from None
