"""What the world shows, read from its nodes, for every reader of the world's light (the bake's
world maps, Lights from Probe): the equirectangular EXR of its Environment Texture, the Background
strength, and the rotation of a Mapping node between a Texture Coordinate (Generated) and the
Environment Texture — the usual way to turn an HDRI. So a turned or brightened HDRI lights the
probes, the world maps and the lamps exactly as Cycles shows it.

The World Probe setting (scene.platelight.world_probe) names the probe file, in world axes; when
the world shows that file (or its sun-less copy made by Lights from Probe), the world's strength
and rotation apply to it as well."""
from __future__ import annotations

import dataclasses
import math
import os

import bpy
import numpy as np

from .. import compat

# Custom property of the sun-less copy of a probe that Lights from Probe puts into the world.
SUNLESS_OF_KEY = "platelight_sunless_of"
IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclasses.dataclass(frozen=True)
class WorldImage:
    """An equirectangular EXR or Radiance .hdr as the world shows it: in world direction d the world is
    ``strength`` × the image in direction ``rotation @ d``."""
    path: str
    strength: float = 1.0
    rotation: tuple = IDENTITY      # 3x3, rows
    node: object = dataclasses.field(default=None, compare=False)   # its Environment Texture node

    @property
    def turned(self) -> bool:
        return not np.allclose(self.rotation, IDENTITY, atol=1e-9)

    def read(self) -> np.ndarray:
        """The world's environment as a float32 lat-long map (rotated, times the strength)."""
        from ..addon.hdr_io import read_probe
        from ..addon.ibl.equirect import rotate_equirect

        env = read_probe(self.path)
        if self.turned:
            env = rotate_equirect(env, self.rotation)
        return env * np.float32(self.strength)

    def to_world(self, direction) -> np.ndarray:
        """A direction of the image as the world direction where the world shows it."""
        return np.asarray(self.rotation, dtype=np.float64).T @ np.asarray(direction, dtype=np.float64)


def _euler_xyz(angles) -> np.ndarray:
    """Blender's XYZ Euler rotation: X first, then Y, then Z (R = Rz Ry Rx)."""
    x, y, z = (float(a) for a in angles)
    cx, sx, cy, sy, cz, sz = math.cos(x), math.sin(x), math.cos(y), math.sin(y), math.cos(z), math.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _lookup_rotation(env_node):
    """The rotation R with which ``env_node`` looks up the image at R·d for the view direction d,
    or None when its Vector input is something else than the view direction turned by a Mapping."""
    vector = env_node.inputs["Vector"]
    if not vector.is_linked:
        return np.eye(3)
    link = vector.links[0]
    node = link.from_node
    if node.bl_idname == "ShaderNodeTexCoord":
        return np.eye(3) if link.from_socket.identifier == "Generated" else None
    if node.bl_idname != "ShaderNodeMapping" or node.mute:
        return None
    inputs = {s.identifier: s for s in node.inputs}
    if any(s.is_linked for name, s in inputs.items() if name != "Vector"):
        return None
    source = inputs["Vector"]
    if not source.is_linked or source.links[0].from_node.bl_idname != "ShaderNodeTexCoord" \
            or source.links[0].from_socket.identifier != "Generated":
        return None
    kind = node.vector_type
    scale = np.array(inputs["Scale"].default_value) if "Scale" in inputs else np.ones(3)
    location = np.array(inputs["Location"].default_value) if "Location" in inputs else np.zeros(3)
    # A direction scaled uniformly and not moved is still the same direction.
    if not (np.allclose(scale, scale[0]) and scale[0] > 0):
        return None
    if kind in ("POINT", "TEXTURE") and np.any(location != 0):
        return None
    rotation = _euler_xyz(inputs["Rotation"].default_value)
    return rotation.T if kind == "TEXTURE" else rotation     # Texture: the inverse transform


def _exr_path(env_node):
    image = env_node.image
    if image is None or env_node.projection != "EQUIRECTANGULAR" or image.packed_file is not None:
        return None
    path = bpy.path.abspath(image.filepath, library=image.library)
    return path if path.lower().endswith((".exr", ".hdr")) and os.path.isfile(path) else None


def _world_chain(world):
    """(Background node, Environment Texture node) when the active World Output shows exactly an
    Environment Texture through a Background (no other node between); else None."""
    tree = compat.shader_tree(world)
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n.is_active_output]
    if len(outputs) != 1 or not outputs[0].inputs["Surface"].is_linked:
        return None
    background = outputs[0].inputs["Surface"].links[0].from_node
    if background.bl_idname != "ShaderNodeBackground" or background.inputs["Strength"].is_linked:
        return None
    color = background.inputs["Color"]
    if not color.is_linked or color.links[0].from_node.bl_idname != "ShaderNodeTexEnvironment":
        return None
    return background, color.links[0].from_node


def world_image(world):
    """The WorldImage the world is exactly (Environment Texture EXR → Background → World Output,
    optionally turned by a Mapping node), or None when the world has to be rendered to know it."""
    chain = _world_chain(world) if world is not None else None
    if chain is None:
        return None
    background, env = chain
    path, rotation = _exr_path(env), _lookup_rotation(env)
    if path is None or rotation is None:
        return None
    return WorldImage(path, float(background.inputs["Strength"].default_value),
                      tuple(map(tuple, rotation)), env)


def probe_image(scene):
    """The scene's probe image: the World Probe file (with the world's strength and rotation when
    the world shows that file), else the world's own image (world_image); None if neither."""
    shown = world_image(scene.world)
    if not scene.platelight.world_probe:
        return shown
    path = os.path.normpath(bpy.path.abspath(scene.platelight.world_probe))
    if shown is not None and path in (os.path.normpath(shown.path),
                                      os.path.normpath(shown.node.image.get(SUNLESS_OF_KEY, ""))):
        return dataclasses.replace(shown, path=path)
    return WorldImage(path)
