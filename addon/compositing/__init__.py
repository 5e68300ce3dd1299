"""bpy-free parts of the compositing: grain measurement and synthesis (grain.py)."""
