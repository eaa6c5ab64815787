"""Run the command-line interface: ``python -m analogy``."""

import sys

from .cli import main

sys.exit(main())
