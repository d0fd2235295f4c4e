"""The package's version: read from the installed distribution's metadata (pyproject.toml is
its one source). A source tree on sys.path without an installed distribution is `0+unknown`."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("constraint-aware")
except PackageNotFoundError:
    __version__ = "0+unknown"

__all__ = ["__version__"]
