"""Scene settings changed for a bake and put back afterwards, one by one, in reverse order."""

_ABSENT = object()      # a custom property that was not there before


class _Item(str):
    """A saved custom property's key (``owner[key]``), told apart from an attribute's name."""


class SceneState:
    """Remembers attribute values and puts them back in reverse order (each restore on its own,
    so one failure cannot leave the rest of the scene changed)."""

    def __init__(self):
        self._saved = []

    def set(self, owner, attr, value):
        self._saved.append((owner, attr, getattr(owner, attr)))
        setattr(owner, attr, value)

    def set_item(self, owner, key, value):
        """Like ``set`` for a custom property ``owner[key]`` (removed again if it was not there)."""
        self._saved.append((owner, _Item(key), owner.get(key, _ABSENT)))
        owner[key] = value

    def restore(self):
        errors = []
        for owner, attr, value in reversed(self._saved):
            try:
                if isinstance(attr, _Item):
                    if value is _ABSENT:
                        owner.pop(attr, None)
                    else:
                        owner[attr] = value
                elif getattr(owner, attr) != value:
                    setattr(owner, attr, value)
            except (ReferenceError, AttributeError, TypeError, ValueError, KeyError) as exc:
                errors.append(f"{attr}: {exc}")
        self._saved.clear()
        return errors
