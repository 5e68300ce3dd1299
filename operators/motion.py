"""Which objects move or deform over the shot: a shadow baked once serves only what stands still.

An object is sampled at frames spread over the scene's range: its world matrix (its own animation,
a parent's, constraints, drivers) and, where something can change its shape (modifiers, shape keys,
animated object data), its evaluated vertices (armatures, shape keys, animated modifier inputs,
geometry nodes that read the scene time). Sampling what Blender evaluates, rather than reading
animation data, catches every way an object can be driven and flags nothing whose keys do not
change it inside the shot."""
from __future__ import annotations

import dataclasses

import bpy
import numpy as np

from ..addon.bake.frames import sample_frames

# frames sampled over the range: every frame of a shot up to this long
SAMPLE_FRAMES = 48
MATRIX_TOLERANCE = 1e-6
# vertices may move this much (of the object's size) between frames and still count as still
SHAPE_TOLERANCE = 1e-5


@dataclasses.dataclass(frozen=True)
class Motion:
    """How one object changes over the shot: ``kind`` "moves" (its place) or "deforms" (its
    shape), first seen at ``frame``."""
    name: str
    kind: str
    frame: int

    def sentence(self) -> str:
        return f"'{self.name}' {self.kind} during the shot (from frame {self.frame})"


def can_change_shape(ob) -> bool:
    """Could anything change ``ob``'s evaluated geometry from frame to frame?"""
    data = getattr(ob, "data", None)
    keys = getattr(data, "shape_keys", None)
    return bool(len(ob.modifiers) or keys is not None
                or getattr(data, "animation_data", None) is not None)


def _vertices(ob, depsgraph):
    evaluated = ob.evaluated_get(depsgraph)
    try:
        mesh = evaluated.to_mesh()
    except RuntimeError:                # no geometry to compare (an empty curve, ...)
        return np.zeros((0, 3))
    try:
        if mesh is None:
            return np.zeros((0, 3))
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        return co.reshape(-1, 3)
    finally:
        evaluated.to_mesh_clear()


def _same_shape(a, b) -> bool:
    if a.shape != b.shape:
        return False
    if not len(a):
        return True
    size = float(np.ptp(a, axis=0).max()) or 1.0
    return bool(np.abs(a - b).max() <= SHAPE_TOLERANCE * size)


KINDS = ("moves", "deforms")


def motions(scene, objects, frames=None, kinds=KINDS) -> dict[str, Motion]:
    """{name: Motion} of the ``objects`` that move or deform over ``frames`` (default: frames
    spread over the scene's range); still objects are absent. The scene's frame is restored.
    ``kinds=("deforms",)`` looks at shapes only: an object that moves and deforms (a walking
    character) is then found as deforming, where by default its first move is reported."""
    objects = list(objects)
    if not objects:
        return {}
    if frames is None:
        frames = sample_frames(scene.frame_start, scene.frame_end, SAMPLE_FRAMES)
    frame0, subframe0 = scene.frame_current, scene.frame_subframe
    placed = objects if "moves" in kinds else []
    shaped = [ob for ob in objects if can_change_shape(ob)] if "deforms" in kinds else []
    if not placed and not shaped:       # nothing that could change: no frame to walk
        return {}
    first_matrix, first_shape, found = {}, {}, {}
    try:
        for frame in frames:
            scene.frame_set(int(frame))
            depsgraph = None
            for ob in objects:
                if ob.name in found:
                    continue
                if ob in placed:
                    matrix = np.array(ob.matrix_world)
                    if ob.name not in first_matrix:
                        first_matrix[ob.name] = matrix
                    elif not np.allclose(matrix, first_matrix[ob.name], atol=MATRIX_TOLERANCE):
                        found[ob.name] = Motion(ob.name, "moves", int(frame))
                        continue
                if ob in shaped:
                    depsgraph = depsgraph or scene_depsgraph(scene)
                    vertices = _vertices(ob, depsgraph)
                    if ob.name not in first_shape:
                        first_shape[ob.name] = vertices
                    elif not _same_shape(vertices, first_shape[ob.name]):
                        found[ob.name] = Motion(ob.name, "deforms", int(frame))
    finally:
        scene.frame_set(frame0, subframe=subframe0)
    return found


def scene_depsgraph(scene):
    """The scene's evaluated dependency graph, as the render will see it."""
    if bpy.context.scene == scene:
        return bpy.context.evaluated_depsgraph_get()
    return scene.view_layers[0].depsgraph
