"""`python -m virtual_reflections ...`: see cli.py."""

import sys

from .cli import main

sys.exit(main())
