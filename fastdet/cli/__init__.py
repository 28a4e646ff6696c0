"""``python -m fastdet``: one module per command (argument parsing and the command's run).
Nothing else in fastdet imports this package."""
from .main import main

__all__ = ["main"]
