"""The repository speaks of the product, not of its making: docs/, README.md and the comments and
docstrings of the Python files say what the product does and why, and git log keeps the history.

Scanned: every Markdown file under docs/ and README.md (whole text), and in the .py files of
addon/, operators/, node_groups/, ui/, drivers/, tools/, tests/ and the top level, the comments and
the bare string statements (docstrings) found by the tokenize module; in tests/bench/ also every
string literal, since those scripts write the docs/bench tables. Code is never scanned: a pytest
fixture's scope argument or a hook's parameter is not prose."""
from __future__ import annotations

import io
import pathlib
import re
import tokenize


REPO = pathlib.Path(__file__).resolve().parents[1]
PY_FOLDERS = ("addon", "operators", "node_groups", "ui", "drivers", "tools", "tests")
BENCH = REPO / "tests" / "bench"

# Words about how the product was made. The word for a running Blender (or render, or pytest
# run) and for a fixture's scope is allowed where it is qualified so.
PATTERNS = {
    "session": re.compile(
        r"(?<!blender )(?<!blender's )(?<!own )(?<!render )(?<!pytest )(?<!test )"
        r"\bsessions?\b(?![- ]scoped?\b)(?! fixtures?\b)", re.I),
    "turn N": re.compile(r"\bturns? \d+", re.I),
    "helper N": re.compile(r"\bhelper-?\d+", re.I),
    "re-ran": re.compile(r"\bre-?ran\b", re.I),
    "in run N": re.compile(r"\b(?:in|from) run \d+", re.I),
    "previous run": re.compile(r"\b(?:previous|earlier|last) runs?\b(?!'s)", re.I),
    "until now": re.compile(r"\buntil now\b", re.I),
    "measured on a day": re.compile(
        r"\b(?:measured|ran|timed) (?:on |last )?(?:(?:mon|tues|wednes|thurs|fri|satur|sun)day"
        r"|yesterday|today|last (?:week|night))\b", re.I),
    "we measured": re.compile(r"\bwe (?:measured|re-?ran|ran|timed|tried)\b", re.I),
    "date": re.compile(r"\b20\d\d-(?:0[1-9]|1[0-2])-(?:0[1-9]|[12]\d|3[01])\b"),
}
# Only in Markdown: which rows of a table were kept from an older run is history of the table.
MARKDOWN_ONLY = {
    "KEEP_ROWS": re.compile(r"\bKEEP_ROWS\b"),
}



def _markdown_files():
    files = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    return [f for f in files if f.is_file()]


def _python_files():
    files = sorted(REPO.glob("*.py"))
    for folder in PY_FOLDERS:
        files += sorted(p for p in (REPO / folder).rglob("*.py") if "__pycache__" not in p.parts)
    return files


def _python_prose(path: pathlib.Path):
    """(line, text) of the comments and bare string statements; every string literal in
    tests/bench/, whose strings become docs/bench."""
    every_string = BENCH in path.parents
    source = path.read_text(encoding="utf-8")
    tokens = [t for t in tokenize.generate_tokens(io.StringIO(source).readline)
              if t.type not in (tokenize.NL,)]
    starts = (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING)
    out = []
    for i, tok in enumerate(tokens):
        if tok.type == tokenize.COMMENT:
            out.append((tok.start[0], tok.string))
        elif tok.type == tokenize.STRING or _is_fstring_start(tok):
            if every_string:
                out.append((tok.start[0], tok.string))
                continue
            if tok.type != tokenize.STRING:
                continue
            before = tokens[i - 1].type if i else tokenize.ENCODING
            j = i
            while j + 1 < len(tokens) and tokens[j + 1].type in (tokenize.STRING, tokenize.COMMENT):
                j += 1
            after = tokens[j + 1].type if j + 1 < len(tokens) else tokenize.ENDMARKER
            if (before in starts or (i and tokens[i - 1].type == tokenize.STRING)) \
                    and after in (tokenize.NEWLINE, tokenize.ENDMARKER):
                out.append((tok.start[0], tok.string))
        elif every_string and tok.type == getattr(tokenize, "FSTRING_MIDDLE", None):
            out.append((tok.start[0], tok.string))
    return out


def _is_fstring_start(tok) -> bool:
    return tok.type == getattr(tokenize, "FSTRING_START", None)


def _hits_in(path: pathlib.Path):
    if path.suffix == ".md":
        text = path.read_text(encoding="utf-8")
        patterns = {**PATTERNS, **MARKDOWN_ONLY}
        chunks = [(n + 1, line) for n, line in enumerate(text.splitlines())]
    else:
        patterns = PATTERNS
        chunks = _python_prose(path)
    hits = []
    for line, text in chunks:
        # a comment or docstring may run over several lines: join them so a phrase broken at a
        # line end is still seen, and count lines from the chunk's start
        flat = re.sub(r"\s*\n\s*(?:#\s*)?", " ", text)
        for name, pattern in patterns.items():
            for m in pattern.finditer(flat):
                hits.append(f"{path.relative_to(REPO).as_posix()}:{line}: {name}: "
                            f"...{flat[max(0, m.start() - 40):m.end() + 40]}...")
    return hits


def _all_files():
    return _markdown_files() + _python_files()


def test_docs_and_comments_speak_of_the_product():
    hits = []
    for path in _all_files():
        hits += _hits_in(path)
    assert not hits, "history of the making, not the product:\n" + "\n".join(hits)


def test_the_patterns_catch_history_and_spare_the_product():
    history = ["Session 21 re-ran every row", "(0.87 in session 7)", "since session 29 the default",
               "in this session", "an earlier session's table", "turn 3 found", "helper-2 measured",
               "helper2's table", "we measured on Tuesday", "as in run 4", "from the previous run",
               "bench of 2026-11-30"]
    product = ["once per Blender session", "Blender's own session folder",
               "Cycles builds the map at each render session", "a session-scoped fixture",
               "one per pytest session", "the bake's turn", "a helper function",
               "an earlier run's bake is reused", "re-run the row", "return 0"]
    for text in history:
        assert any(p.search(text) for p in PATTERNS.values()), text
    for text in product:
        assert not any(p.search(text) for p in PATTERNS.values()), text


def test_prose_is_read_from_comments_and_docstrings_only(tmp_path):
    source = ('"""Module docstring."""\n'
              '@pytest.fixture(scope="session")\n'
              'def f(session):\n'
              '    """Docstring of f."""\n'
              '    x = "a string"  # a comment\n'
              '    return x\n')
    path = tmp_path / "m.py"
    path.write_text(source)
    texts = [t for _, t in _python_prose(path)]
    assert texts == ['"""Module docstring."""', '"""Docstring of f."""', "# a comment"]
