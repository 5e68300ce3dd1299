"""`python -m platelight ...`: the command-line interface (see addon/cli.py)."""
import sys

from .addon.cli import main

sys.exit(main())
