"""Errors raised on bad user input: each names the file, the line (when there is one) and the field."""

from __future__ import annotations

from pathlib import Path


class OnebitError(Exception):
    """Base class of every error onebit raises about its input or configuration."""


class InputError(OnebitError):
    """A user file or setting that cannot be used.

    The message reads ``FILE:LINE: field 'FIELD': what is wrong`` with the parts that are known.
    """

    def __init__(
        self,
        reason: str,
        *,
        file: str | Path | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.reason = reason
        self.file = None if file is None else str(file)
        self.line = line
        self.field = field
        where = ""
        if self.file is not None:
            where = self.file
            if line is not None:
                where += f":{line}"
            where += ": "
        what = f"field '{field}': " if field else ""
        super().__init__(f"{where}{what}{reason}")


class SiteError(InputError):
    """A ``site.toml`` that cannot be used; names the key and what is wrong with it."""


class ConfigError(OnebitError, ValueError):
    """A configuration value outside its declared bounds; names the field, value and range."""
