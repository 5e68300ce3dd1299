"""Which CG objects shadow themselves: the rays of addon/material/self_occlusion.py cast against
each object's evaluated surface at the current frame (mathutils' BVH tree)."""
from __future__ import annotations

import numpy as np
from mathutils import Vector
from mathutils.bvhtree import BVHTree

from ...addon.material.self_occlusion import SELF_SHADOWING_AT, occluded_fraction, rays


def world_triangles(ob, depsgraph) -> np.ndarray:
    """(T, 3, 3): the triangles of ``ob``'s evaluated surface in world space (where areas count)."""
    evaluated = ob.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        if mesh is None:
            return np.zeros((0, 3, 3))
        mesh.calc_loop_triangles()
        vertices = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", vertices)
        indices = np.empty(len(mesh.loop_triangles) * 3, int)
        mesh.loop_triangles.foreach_get("vertices", indices)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(evaluated.matrix_world)
    vertices = vertices.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
    return vertices[indices.reshape(-1, 3)]


def self_occlusion(ob, depsgraph) -> float:
    """The fraction of its own sky ``ob``'s surface hides from itself (0: convex)."""
    triangles = world_triangles(ob, depsgraph)
    if not len(triangles):
        return 0.0
    origins, directions = rays(triangles)
    # the tree is in the object's own space: an affine map keeps which rays hit
    tree = BVHTree.FromObject(ob, depsgraph)
    to_local = np.linalg.inv(np.array(ob.evaluated_get(depsgraph).matrix_world))
    origins = origins @ to_local[:3, :3].T + to_local[:3, 3]
    directions = directions @ to_local[:3, :3].T
    hits = np.zeros(directions.shape[:2], bool)
    for i, (origin, fan) in enumerate(zip(origins, directions)):
        start = Vector(origin)
        for j, direction in enumerate(fan):
            hits[i, j] = tree.ray_cast(start, Vector(direction))[0] is not None
    return occluded_fraction(hits)


def self_shadowing(objects, depsgraph) -> dict:
    """{name: self-occlusion} of the ``objects`` that hide at least SELF_SHADOWING_AT of their sky."""
    found = {}
    for ob in objects:
        fraction = self_occlusion(ob, depsgraph)
        if fraction >= SELF_SHADOWING_AT:
            found[ob.name] = fraction
    return found
