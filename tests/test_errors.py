"""User-facing sentences fit where they are shown: the engine names what the user must give in
plain words, the command line puts in its flags and operators their fields."""
from __future__ import annotations

import ast

import numpy as np
import pytest

import support
from platelight.addon.capture import mirror_ball
from platelight.addon.errors import PlateLightError
from platelight.addon.wording import Sentence, worded
from platelight.cli import FLAGS


def test_inputs_are_worded_per_front_end():
    err = PlateLightError("No ball in {a}.png; give its circle with {ball}.", ball="its centre and radius")
    assert str(err) == "No ball in {a}.png; give its circle with its centre and radius."   # braces in names stay
    assert err.worded(FLAGS) == "No ball in {a}.png; give its circle with --ball CX,CY,R."
    assert err.worded({"ball": "the Ball Circle field"}).endswith("with the Ball Circle field.")
    plain = PlateLightError("File not found: {x}.exr")
    assert str(plain) == plain.worded(FLAGS) == "File not found: {x}.exr"


def test_warnings_are_worded_per_front_end_too():
    warning = Sentence("shoot brackets (or give {grey_card})", grey_card="a grey card's box")
    assert warning == "shoot brackets (or give a grey card's box)"
    assert worded(warning, FLAGS) == "shoot brackets (or give --grey-card)"
    assert worded("a plain warning", FLAGS) == "a plain warning"


def test_an_engine_error_names_no_flag_and_the_cli_names_its_flag():
    flat = np.full((64, 96, 3), 0.5, np.float32)          # no ball anywhere
    with pytest.raises(PlateLightError) as caught:
        mirror_ball.find_ball(flat)
    assert "--" not in str(caught.value)
    assert "--ball CX,CY,R" in caught.value.worded(FLAGS)


def _sentences(path):
    """String pieces of every PlateLightError(...) and warning Sentence(...) in ``path``."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ("PlateLightError", "Sentence") \
                and node.args:
            for piece in ast.walk(node.args[0]):
                if isinstance(piece, ast.Constant) and isinstance(piece.value, str):
                    yield node.lineno, piece.value


def test_engine_sentences_name_no_command_line_flags():
    """Only the command-line front ends (cli_*.py) may say --flag; the rest of the engine is also
    shown inside Blender, where there are no flags."""
    found = []
    for path in sorted((support.REPO / "addon").rglob("*.py")):
        if path.name.startswith("cli_"):
            continue
        found += [f"{path.relative_to(support.REPO)}:{line}: {text}" for line, text in _sentences(path)
                  if " --" in f" {text}" or text.startswith("--")]
    assert not found, found


def test_typed_numbers_take_fractions_and_refuse_what_is_not_a_number():
    from platelight.addon.wording import typed_numbers

    assert typed_numbers("1/250, 0.004,,2") == [0.004, 0.004, 2.0]
    assert typed_numbers("") == []
    for bad in ("1/0", "a", "1/2/3", "1/"):
        with pytest.raises(ValueError):
            typed_numbers(bad)
