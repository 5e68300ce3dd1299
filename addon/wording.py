"""Sentences that fit where they are shown. The engine does not know whether the command line or
Blender shows its errors and warnings, so a sentence that asks the user for something names that
input as ``{key}`` with plain words (``inputs``); the front end puts in its own name: the command
line its flag (CLI_FLAGS), an operator its field (operators/common.py)."""
from __future__ import annotations

# How the command line names each input.
CLI_FLAGS = {
    "ball": "--ball CX,CY,R",
    "calibration": "calibration file (--calibration)",
    "dictionary": "--dictionary",
    "dpi": "--dpi",
    "exposures": "--exposures T1,T2,...",
    "focal": "focal length (--focal-px or --focal-mm)",
    "grey_card": "--grey-card",
    "part": "--part",
    "samples": "--samples",
}


def typed_numbers(text: str) -> list[float]:
    """Comma-separated numbers as a user types them, a fraction ('1/250') counting as its value
    (exposure times are written so); ValueError where one is not a number."""
    values = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        numerator, slash, denominator = item.partition("/")
        try:
            values.append(float(numerator) / float(denominator) if slash else float(item))
        except ZeroDivisionError:
            raise ValueError(f"{item!r} divides by zero") from None
    return values


def fill(template: str, inputs: dict, names: dict) -> str:
    """``template`` with each ``{key}`` of ``inputs`` replaced by ``names[key]`` or its plain words.
    Plain replacement, not str.format: file names in the sentence may hold braces."""
    for key, plain in inputs.items():
        template = template.replace("{" + key + "}", names.get(key, plain))
    return template


class Sentence(str):
    """A warning that names inputs like PlateLightError does; as a str it is the plain wording."""

    def __new__(cls, template: str, **inputs: str):
        sentence = super().__new__(cls, fill(template, inputs, {}))
        sentence.template, sentence.inputs = template, inputs
        return sentence

    def worded(self, names: dict) -> str:
        return fill(self.template, self.inputs, names)


def worded(text, names: dict) -> str:
    """Any error or warning in a front end's words (plain strings pass unchanged)."""
    return text.worded(names) if hasattr(text, "worded") else str(text)
