"""The one exception type a user ever sees: its message is a single clear sentence."""
from .wording import fill


class PlateLightError(Exception):
    """A problem with the user's input or environment (not a bug), shown by the CLI on stderr with
    a non-zero exit status and by operators through ``self.report``.

    The engine does not know where it runs, so a sentence that tells the user what to give names
    that input as ``{key}`` and ``inputs`` holds its plain wording (``str(err)``); each front end
    puts in its own name with ``worded()``: the CLI its flag, an operator its field (wording.py)."""

    def __init__(self, message: str, **inputs: str):
        self.template = message
        self.inputs = inputs
        super().__init__(fill(message, inputs, {}))

    def worded(self, names: dict[str, str]) -> str:
        """The sentence with the front end's ``names`` for the inputs it names (others stay plain)."""
        return fill(self.template, self.inputs, names)
