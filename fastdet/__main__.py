"""``python -m fastdet`` → :func:`fastdet.cli.main`."""
import sys

from .cli.main import main

sys.exit(main())
