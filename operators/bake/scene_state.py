"""Scene settings changed for a bake and put back afterwards, one by one, in reverse order."""


class SceneState:
    """Remembers attribute values and puts them back in reverse order (each restore on its own,
    so one failure cannot leave the rest of the scene changed)."""

    def __init__(self):
        self._saved = []

    def set(self, owner, attr, value):
        self._saved.append((owner, attr, getattr(owner, attr)))
        setattr(owner, attr, value)

    def restore(self):
        errors = []
        for owner, attr, value in reversed(self._saved):
            try:
                if getattr(owner, attr) != value:
                    setattr(owner, attr, value)
            except (ReferenceError, AttributeError, TypeError, ValueError) as exc:
                errors.append(f"{attr}: {exc}")
        self._saved.clear()
        return errors
