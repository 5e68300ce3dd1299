"""The compositor wiring behind the multilayer output (addon/farm/multilayer.py): the CG view
layer's Depth, Normal and Cryptomatte (object) passes switched on, and one File Output node in
single-image mode that writes the CG, Shadows, Depth, Normal and CryptoObject00-02 of each frame
as float32 EXRs into a folder (Blender 5.2's multilayer File Output writes only its first input).
Idempotent: re-running rewires the same node. The passes do not change the composite's pixels."""
import os
import shutil
import tempfile

import bpy

from .. import compat
from ..addon import names
from ..addon.errors import PlateLightError
from ..addon.farm.multilayer import CRYPTO_LEVELS, CRYPTO_NAME, assemble
from .compositor_tree import float_exr_file_output
# file stem -> (node, output socket) in the PlateLight Composite tree
_SOURCES = (("CG", "diff", "CG"), ("Shadows", "diff", "Shadows"), ("Depth", "layer", "Depth"),
            ("Normal", "layer", "Normal"),
            *((f"{CRYPTO_NAME}{k:02d}", "layer", f"{CRYPTO_NAME}{k:02d}") for k in range(CRYPTO_LEVELS)))
PASS_FILES = tuple(stem for stem, _node, _socket in _SOURCES)


def wire_pass_files(scene, directory):
    """Switch on the passes and (re)wire the File Output node to write into ``directory``."""
    tree = compat.compositor_tree(scene)
    if tree is None or names.DIFFERENTIAL_GROUP not in tree.nodes or names.LAYER_CG not in tree.nodes:
        raise RuntimeError("no PlateLight composite")
    layer = scene.view_layers[names.LAYER_CG]
    layer.use_pass_z = True
    layer.use_pass_normal = True
    layer.use_pass_cryptomatte_object = True
    layer.pass_cryptomatte_depth = 2 * CRYPTO_LEVELS
    nodes = {"diff": tree.nodes[names.DIFFERENTIAL_GROUP], "layer": tree.nodes[names.LAYER_CG]}
    node = float_exr_file_output(tree, names.PASS_FILES_NODE, directory, PASS_FILES, (400, -600))
    node.format.exr_codec = "NONE"          # a scratch file, read once
    for stem, owner, socket in _SOURCES:
        tree.links.new(nodes[owner].outputs[socket], node.inputs[stem])
    return node


def phantom_names(scene):
    """Names of the objects that stand in for real things (their coverage is the holdout matte):
    setup_composite's phantom collection (read without the add-on registered, as the CLI runs)."""
    coll = bpy.data.collections.get(names.PHANTOM_COLLECTION)
    return sorted(ob.name for ob in coll.all_objects) if coll is not None else []


class MultilayerPasses:
    """For ``python -m platelight render --format multilayer``: the pass files of each frame go to
    a scratch folder in the machine's temporary space (never beside the frames) and are joined
    with the composite into one multilayer EXR before the frame's whole-file commit."""

    def __init__(self, scene):
        self.phantoms = phantom_names(scene)
        self.scratch = tempfile.mkdtemp(prefix="platelight-passes-")
        try:
            wire_pass_files(scene, self.scratch + os.sep)
        except RuntimeError:
            self.close()
            raise PlateLightError("--format multilayer needs the PlateLight composite; run Set Up "
                                  "Composite (platelight.setup_composite) in the .blend first.") from None

    def join(self, frame, composite):
        """Replace the frame's rendered ``composite`` (a temporary file) by the multilayer file."""
        files = {stem: compat.file_output_path(self.scratch, stem, frame) for stem in PASS_FILES}
        for stem, path in files.items():
            if not os.path.isfile(path):
                raise PlateLightError(f"Blender wrote no {stem} pass for frame {frame}; see the render log.")
        joined = composite + ".joined.exr"
        assemble(composite, files, self.phantoms, joined)
        os.replace(joined, composite)
        for path in files.values():
            os.unlink(path)

    def close(self):
        shutil.rmtree(self.scratch, ignore_errors=True)
