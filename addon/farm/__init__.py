"""Render-farm support, bpy-free: Open Job Description bundles (jobs.py), a small YAML writer
(yaml_out.py), multilayer EXRs with named passes (multilayer.py) and farm-log progress
(progress.py). The Flamenco job type is ``flamenco/platelight.js``."""
