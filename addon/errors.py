"""The one exception type a user ever sees: its message is a single clear sentence."""


class PlateLightError(Exception):
    """A problem with the user's input or environment (not a bug). ``str(err)`` is shown as is:
    by the CLI on stderr with a non-zero exit status, by operators through ``self.report``."""
