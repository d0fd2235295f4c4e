"""Exception hierarchy: every error the library raises on purpose is a `CapError`."""

from __future__ import annotations


class CapError(Exception):
    """Base class of the library's errors."""


class InvalidInputError(CapError, ValueError):
    """An argument has the wrong shape, a non-finite value or an out-of-range value."""


class UnknownNameError(CapError, KeyError):
    """A name (task, controller, preset, backend) is not one of the valid names."""

    def __init__(self, kind: str, name: str, valid: list[str] | tuple[str, ...]) -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid names: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class PolicyFileError(CapError):
    """A policy file or its JSON card is missing, malformed or inconsistent."""
