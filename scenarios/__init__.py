"""Built-in scenario files (*.toml in this folder) and their loader."""

from .loader import builtin_names, builtin_path, default_run_names, load, parse

__all__ = ["builtin_names", "builtin_path", "default_run_names", "load", "parse"]
