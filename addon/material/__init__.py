"""bpy-free side of the PlateLight SBRDF material: parameters, JSON files, Principled conversion,
and a numpy evaluation of the paper's Eq 1-7 (used by the add-on for previews and checks)."""
