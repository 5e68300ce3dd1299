"""`python -m platelight ...`: the command-line interface (see cli.py)."""
import sys

from .cli import main

code = main()
if "bpy" in sys.modules:        # a subcommand ran Blender: its shutdown is handled there
    from . import compat

    compat.exit_process(code)
sys.exit(code)
