"""Write the YAML a job bundle holds (mappings, lists, strings, numbers, booleans) without PyYAML,
which Blender does not ship. Strings are double-quoted JSON strings (valid YAML double-quoted
scalars) except multi-line ones, which become literal blocks so embedded scripts stay readable."""
from __future__ import annotations

import json


def _scalar(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return json.dumps(value)
    return json.dumps(str(value), ensure_ascii=False)


def _lines(value, indent: int):
    pad = " " * indent
    if isinstance(value, dict):
        for key, item in value.items():
            head = f"{pad}{key}:"
            yield from _item(head, item, indent)
    elif isinstance(value, list):
        for item in value:
            yield from _item(f"{pad}-", item, indent, in_list=True)
    else:
        yield pad + _scalar(value)


def _item(head: str, item, indent: int, in_list: bool = False):
    if isinstance(item, str) and "\n" in item:
        yield f"{head} |{'' if item.endswith(chr(10)) else '-'}"
        for line in item.rstrip("\n").split("\n"):
            yield (" " * (indent + 2) + line) if line else ""
    elif isinstance(item, (dict, list)) and item:
        if in_list and isinstance(item, dict):
            # "- key: value" with the rest of the mapping aligned under the first key
            nested = list(_lines(item, indent + 2))
            yield f"{head} {nested[0].lstrip()}"
            yield from nested[1:]
        else:
            yield head
            yield from _lines(item, indent + 2)
    elif isinstance(item, (dict, list)):
        yield f"{head} {'{}' if isinstance(item, dict) else '[]'}"
    else:
        yield f"{head} {_scalar(item)}"


def dump(data: dict) -> str:
    """YAML text of ``data`` (a mapping), block style."""
    return "\n".join(_lines(data, 0)) + "\n"
