"""The layers stay apart: addon/ is the bpy-free engine (every module imports with bpy unavailable
and imports nothing above it), and no modules import each other in a circle."""
from __future__ import annotations

import ast
import subprocess
import sys

import support

PACKAGE = "platelight"
BLENDER_MODULES = ("bpy", "bmesh", "mathutils", "bpy_extras", "bl_operators", "bl_ui", "gpu")
SKIP_DIRS = {".git", ".venv", "tests", "tools", "docs", "build", "dist", "out", "bench_out", "presets",
             "requirements", "__pycache__"}


def package_modules():
    """module name -> path of every .py file of the package (tests, tools and presets aside)."""
    modules = {}
    for path in sorted(support.REPO.rglob("*.py")):
        rel = path.relative_to(support.REPO)
        if set(rel.parts[:-1]) & SKIP_DIRS or rel.parts[0].startswith(".venv"):
            continue
        parts = list(rel.with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join([PACKAGE, *parts])] = path
    return modules


def imports_of(name, path):
    """Absolute names of everything ``path`` imports, at the top or inside functions."""
    is_package = path.name == "__init__.py"
    here = name.split(".") if is_package else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def test_every_engine_module_imports_without_blender():
    engine = [n for n in package_modules() if n == f"{PACKAGE}.addon" or n.startswith(f"{PACKAGE}.addon.")]
    assert len(engine) >= 30, engine      # the discovery found the engine
    code = ("import importlib, sys\n"
            f"for blocked in {BLENDER_MODULES!r}:\n"
            "    sys.modules[blocked] = None   # `import bpy` raises ImportError\n"
            "failed = []\n"
            f"for name in {engine!r}:\n"
            "    try:\n"
            "        importlib.import_module(name)\n"
            "    except Exception as exc:\n"
            "        failed.append(f'{name}: {exc!r}')\n"
            "assert not failed, failed\n"
            "print(len([m for m in sys.modules if m.startswith('platelight.addon')]))\n")
    proc = subprocess.run([sys.executable, "-c", code], env=support.cli_env(), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout.split()[-1]) >= len(engine)


def test_engine_imports_nothing_above_it():
    modules = package_modules()
    wrong = []
    for name, path in modules.items():
        if not (name == f"{PACKAGE}.addon" or name.startswith(f"{PACKAGE}.addon.")):
            continue
        for imported in imports_of(name, path):
            top = imported.split(".")[0]
            if top in BLENDER_MODULES:
                wrong.append(f"{name} imports {imported}")
            elif top == PACKAGE and imported != PACKAGE and not imported.startswith(f"{PACKAGE}.addon"):
                wrong.append(f"{name} imports {imported}")
    assert not wrong, wrong


def test_no_import_circles():
    modules = package_modules()
    graph = {}
    for name, path in modules.items():
        deps = set()
        for imported in imports_of(name, path):
            # `from .x import y` names the module x (or x.y when y is a module)
            while imported and imported not in modules:
                imported = imported.rpartition(".")[0]
            if imported and imported != name and imported != PACKAGE:
                deps.add(imported)
        graph[name] = deps
    # parent packages are imported by their children implicitly; an __init__ that imports its
    # own children is not a circle, so only edges between different files count
    state, stack, circles = {}, [], []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for dep in sorted(graph[node]):
            if node.startswith(dep + "."):
                continue
            if state.get(dep) == "open":
                circles.append(" -> ".join(stack[stack.index(dep):] + [dep]))
            elif dep not in state:
                visit(dep)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node)
    assert not circles, circles


def test_datablock_names_are_written_once():
    """Datablocks and nodes are made and found by the names in addon/names.py, not by literals:
    no `.new("PlateLight …")`, `.get("PlateLight …")` or `nodes["PlateLight …"]` elsewhere."""
    found = []
    for name, path in package_modules().items():
        if name == f"{PACKAGE}.addon.names":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                    and node.func.attr in ("new", "get", "load") and node.args:
                key = node.args[0]
            elif isinstance(node, ast.Subscript):
                key = node.slice
            else:
                continue
            if isinstance(key, ast.Constant) and isinstance(key.value, str) and key.value.startswith("PlateLight "):
                found.append(f"{path.relative_to(support.REPO)}:{node.lineno}: {key.value!r}")
    assert not found, found
