"""Per-object probe baking, the bpy-free half: frame ranges, content hashes, which maps an
object needs, camera-frustum culling and where maps live. operators/bake/ is the Blender side."""
