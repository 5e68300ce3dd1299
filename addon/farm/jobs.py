"""An Open Job Description job bundle (AWS Deadline Cloud's layout) for a PlateLight shot: a bake
step (the probes of every frame, one task), then a render step that depends on it, whose tasks are
chunks of frames. Both steps run PlateLight's own commands, ``python -m platelight bake`` and
``python -m platelight render``, so a farm renders exactly what a workstation renders.

The bundle is self-contained: the scene and every file it reads live under ``JOBDIR/scene`` with
paths relative to the .blend, and every PATH parameter defaults to a path relative to the
template (OpenJD joins relative defaults to the template's folder and refuses absolute ones), so
``openjd run JOBDIR/template.yaml`` runs the whole job with no other argument, here or on any
machine the folder is copied to.

    JOBDIR/template.yaml           the job (jobtemplate-2023-09, TASK_CHUNKING extension)
    JOBDIR/parameter_values.yaml   the exported values (Deadline's submitter reads them)
    JOBDIR/asset_references.yaml   inputs (scene/) and outputs (output/, the maps) for job attachments
    JOBDIR/scene/NAME.blend        the scene, its plate, probe and grain files beside it
    JOBDIR/output/                 the rendered frames (the OutputDir parameter's default)
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from ..errors import PlateLightError
from . import yaml_out

TEMPLATE = "template.yaml"
PARAMETER_VALUES = "parameter_values.yaml"
ASSET_REFERENCES = "asset_references.yaml"
SCENE_FOLDER = "scene"
OUTPUT_FOLDER = "output"
MAPS_FOLDER = "platelight_maps"            # the maps folder the bundle's scene is given (//platelight_maps)
BAKE_STEP = "Bake Probes"
RENDER_STEP = "Render Frames"
FORMATS = ("exr", "multilayer", "png")


@dataclass
class FarmJob:
    """What a bundle runs. Paths are relative to the bundle folder, '/'-separated."""
    name: str                                 # the job's name on the farm
    scene: str                                # e.g. scene/shot.blend
    frames: list[int]
    chunk: int = 1
    output: str = OUTPUT_FOLDER
    prefix: str = "composite"                 # render --name
    format: str = "exr"                       # render --format
    python: str = "python"                    # the interpreter that has PlateLight and bpy
    bake: bool = True                         # False when the scene has no PlateLight objects
    inputs: list[str] = field(default_factory=list)   # extra input files (relative), for asset references

    def check(self) -> None:
        if self.chunk < 1:
            raise PlateLightError(f"The chunk size must be at least 1 frame, not {self.chunk}.")
        if not self.frames:
            raise PlateLightError("The job has no frames to render.")
        if self.format not in FORMATS:
            raise PlateLightError(f"The output format must be one of {', '.join(FORMATS)}, not {self.format!r}.")
        for path in [self.scene, self.output, *self.inputs]:
            if os.path.isabs(path) or path.replace("\\", "/").split("/")[0] == "..":
                raise PlateLightError(f"Bundle paths must stay inside the bundle, not {path}.")


def range_expression(frames: list[int]) -> str:
    """Sorted frames as an OpenJD range expression that PlateLight's --frames also reads: 1-4,7."""
    parts = []
    for run in chunks(frames, len(frames)):
        parts.append(str(run[0]) if len(run) == 1 else f"{run[0]}-{run[-1]}")
    return ",".join(parts)


def chunks(frames: list[int], size: int) -> list[list[int]]:
    """The render tasks: consecutive runs of at most ``size`` frames (OpenJD's contiguous chunks
    of the same range expression; used to report the task count and by the Flamenco script's tests)."""
    if size < 1:
        raise PlateLightError(f"The chunk size must be at least 1 frame, not {size}.")
    frames = sorted(set(frames))
    out, run = [], []
    for frame in frames:
        if run and (frame != run[-1] + 1 or len(run) == size):
            out.append(run)
            run = []
        run.append(frame)
    return out + [run]


def bake_args(scene: str, frames: str) -> list[str]:
    """``python -m platelight`` arguments of the bake step (also the Flamenco script's)."""
    return ["bake", scene, "--frames", frames, "--quiet"]


def render_args(scene: str, out: str, frames: str, prefix: str, fmt: str) -> list[str]:
    """``python -m platelight`` arguments of one render task."""
    return ["render", scene, "--out", out, "--frames", frames, "--name", prefix, "--format", fmt, "--quiet"]


def _parameters(job: FarmJob) -> list[dict]:
    return [
        {"name": "SceneFile", "type": "PATH", "objectType": "FILE", "dataFlow": "IN",
         "default": job.scene,
         "description": "The PlateLight .blend (relative paths: its plate and probe files lie beside it).",
         "userInterface": {"control": "CHOOSE_INPUT_FILE", "label": "Scene File",
                           "fileFilters": [{"label": "Blender files", "patterns": ["*.blend"]}]}},
        {"name": "OutputDir", "type": "PATH", "objectType": "DIRECTORY", "dataFlow": "OUT",
         "default": job.output, "description": "Folder of the rendered frames.",
         "userInterface": {"control": "CHOOSE_DIRECTORY", "label": "Output Folder"}},
        {"name": "Frames", "type": "STRING", "default": range_expression(job.frames),
         "description": "Frames to bake and render, e.g. 1-100 or 1-10,15.",
         "userInterface": {"control": "LINE_EDIT", "label": "Frames"}},
        {"name": "ChunkSize", "type": "INT", "default": job.chunk, "minValue": 1,
         "description": "Frames per render task.",
         "userInterface": {"control": "SPIN_BOX", "label": "Chunk Size"}},
        {"name": "OutputName", "type": "STRING", "default": job.prefix,
         "description": "File name prefix of the frames (NAME_0001.exr).",
         "userInterface": {"control": "LINE_EDIT", "label": "Output Name"}},
        {"name": "OutputFormat", "type": "STRING", "default": job.format, "allowedValues": list(FORMATS),
         "description": "exr: the composite; multilayer: the composite and named passes; png: 8-bit.",
         "userInterface": {"control": "DROPDOWN_LIST", "label": "Output Format"}},
        {"name": "PlateLightPython", "type": "STRING", "default": job.python,
         "description": "A Python interpreter that runs `python -m platelight` (bpy and PlateLight installed).",
         "userInterface": {"control": "LINE_EDIT", "label": "PlateLight Python"}},
    ]


def _action(args: list[str]) -> dict:
    return {"onRun": {"command": "{{Param.PlateLightPython}}", "args": ["-m", "platelight", *args],
                      "cancelation": {"mode": "NOTIFY_THEN_TERMINATE"}}}


def template(job: FarmJob) -> dict:
    """The job template (jobtemplate-2023-09) as plain data."""
    job.check()
    steps = []
    if job.bake:
        steps.append({
            "name": BAKE_STEP,
            "description": "Bake every PlateLight object's probe maps for all frames (skips what is "
                           "already baked from the same inputs).",
            "script": {"actions": _action(bake_args("{{Param.SceneFile}}", "{{Param.Frames}}"))},
        })
    render = {
        "name": RENDER_STEP,
        "description": "Render the composite, a chunk of frames per task (keeps complete frames, "
                       "never leaves a half-written one).",
        "parameterSpace": {"taskParameterDefinitions": [{
            "name": "Frame", "type": "CHUNK[INT]", "range": "{{Param.Frames}}",
            "chunks": {"defaultTaskCount": "{{Param.ChunkSize}}", "rangeConstraint": "CONTIGUOUS"}}]},
        "script": {"actions": _action(render_args("{{Param.SceneFile}}", "{{Param.OutputDir}}",
                                                  "{{Task.Param.Frame}}", "{{Param.OutputName}}",
                                                  "{{Param.OutputFormat}}"))},
    }
    if job.bake:
        render["dependencies"] = [{"dependsOn": BAKE_STEP}]
    steps.append(render)
    return {
        "specificationVersion": "jobtemplate-2023-09",
        "extensions": ["TASK_CHUNKING"],
        "name": job.name,
        "description": "PlateLight: bake the probes, then render the composite onto the plate.",
        "parameterDefinitions": _parameters(job),
        "steps": steps,
    }


def parameter_values(job: FarmJob) -> dict:
    """Deadline Cloud's parameter_values.yaml: the exported values (the template's defaults)."""
    return {"parameterValues": [{"name": p["name"], "value": p["default"]} for p in _parameters(job)]}


def asset_references(job: FarmJob) -> dict:
    """Deadline Cloud's asset_references.yaml: what job attachments upload and download."""
    scene_dir = os.path.dirname(job.scene) or "."
    return {"assetReferences": {
        "inputs": {"directories": [scene_dir], "filenames": list(job.inputs)},
        "outputs": {"directories": [job.output, f"{scene_dir}/{MAPS_FOLDER}"]},
        "referencedPaths": [],
    }}


def write_bundle(folder: str, job: FarmJob) -> list[str]:
    """Write the bundle's YAML files into ``folder`` (atomically each); returns their paths."""
    from ..fileio import write_text_atomic

    written = []
    for filename, data in ((TEMPLATE, template(job)), (PARAMETER_VALUES, parameter_values(job)),
                           (ASSET_REFERENCES, asset_references(job))):
        path = os.path.join(folder, filename)
        write_text_atomic(path, yaml_out.dump(data))
        written.append(path)
    return written
