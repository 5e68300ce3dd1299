"""Builders for PlateLight's node groups (shader and compositor). Each builder is idempotent:
running it again updates the existing group in place, never creates a duplicate."""
