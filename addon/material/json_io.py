"""SBRDF material files (JSON): the paper's "material editor that exports its configuration".

    {"format": "platelight-sbrdf", "version": 3, "name": "Chrome",
     "parameters": {"diffuse_albedo": [0, 0, 0], "glossiness": 1.0, ...}}

Reading validates everything before anything is applied: a malformed file, another format, a
newer version, an unknown or mistyped parameter raises PlateLightError (one sentence). Missing
parameters take their defaults; values out of range are clamped (as the node sockets do).
Version 1 predates ``paper_falloff``: those materials were made with the paper's g', so a version-1
file without it reads as paper_falloff = 1 (the look it was saved with). Version 3 adds
``fresnel_peak``; an older file without it reads as 1, the paper's Fresnel it was made with, and an
older PlateLight reading a version-3 file says it is newer rather than that a parameter is unknown."""
from __future__ import annotations

import dataclasses
import json
import os

from ..errors import PlateLightError
from .params import SBRDFParams, validate_value

FORMAT = "platelight-sbrdf"
VERSION = 3


def params_to_json(params: SBRDFParams, name: str = "") -> str:
    data = {"format": FORMAT, "version": VERSION, "name": name,
            "parameters": {k: list(v) if isinstance(v, tuple) else v
                           for k, v in dataclasses.asdict(params).items()}}
    return json.dumps(data, indent=2) + "\n"


def params_from_json(text: str, source: str = "the file") -> tuple[SBRDFParams, str]:
    """(parameters, name) from JSON text; PlateLightError on anything unexpected."""
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise PlateLightError(f"{source} is not valid JSON ({exc.msg} at line {exc.lineno}).") \
            from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise PlateLightError(f"{source} is not a PlateLight SBRDF material "
                              f"(expected \"format\": \"{FORMAT}\").")
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise PlateLightError(f"{source} has no valid \"version\" (expected an integer >= 1).")
    if version > VERSION:
        raise PlateLightError(f"{source} is SBRDF material version {version}; this PlateLight "
                              f"reads up to version {VERSION}.")
    values = data.get("parameters")
    if not isinstance(values, dict):
        raise PlateLightError(f"{source} has no \"parameters\" object.")
    checked = {key: validate_value(key, value) for key, value in values.items()}
    if version == 1:
        checked.setdefault("paper_falloff", 1.0)
    name = data.get("name", "")
    return dataclasses.replace(SBRDFParams(), **checked).clamped(), str(name)


def save_params(path: str | os.PathLike, params: SBRDFParams, name: str = "") -> None:
    path = os.fspath(path)
    try:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(params_to_json(params, name))
    except OSError as exc:
        raise PlateLightError(f"Cannot write {path}: {exc.strerror}.") from None


def load_params(path: str | os.PathLike) -> tuple[SBRDFParams, str]:
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise PlateLightError(f"File not found: {path}")
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise PlateLightError(f"Cannot read {path}: {exc}.") from None
    return params_from_json(text, source=os.path.basename(path))
