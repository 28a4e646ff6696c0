"""``python -m fastdet`` → :func:`fastdet.cli.main`."""
import sys

from .cli import main

sys.exit(main())
