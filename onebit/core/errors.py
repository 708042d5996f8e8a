"""Errors raised on bad user input: each names the file, the line (when there is one) and the field.

Every message is bounded (:func:`bounded`): a value quoted from user input (a 50 MB line, a
huge TOML string) is cut to :data:`MAX_QUOTE` characters and a whole message to
:data:`MAX_MESSAGE`, with the full length stated, so no error floods a console or a
``run.toml``.
"""

from __future__ import annotations

import errno
from pathlib import Path

#: Characters of raw user text (a rejected line, a bad value) quoted in a reject or a message.
MAX_QUOTE = 200
#: Characters of a whole error message.
MAX_MESSAGE = 2000


def bounded(text: str, limit: int = MAX_QUOTE) -> str:
    """``text`` cut to ``limit`` characters, stating the full length when it was cut.

    >>> bounded("x" * 300, 10)
    'xxxxxxxxxx... (300 characters)'
    """
    text = str(text)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


class OnebitError(Exception):
    """Base class of every error onebit raises about its input or configuration.

    The message is bounded to :data:`MAX_MESSAGE` characters (:func:`bounded`).
    """

    def __init__(self, message: object = "", *args: object) -> None:
        super().__init__(bounded(str(message), MAX_MESSAGE), *args)


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
        self.reason = reason = bounded(reason, MAX_MESSAGE)
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


#: ``errno`` values and message fragments of a full disk (or an exhausted quota). Rust writers
#: (polars) report it as ``OSError``/``ComputeError`` text without ``errno``: "No space left on
#: device (os error 28)".
_DISK_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
_DISK_FULL_TEXT = ("no space left on device", "os error 28", "disk quota exceeded", "os error 122")


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` (or an exception it was raised from) says the disk is full."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in _DISK_FULL_ERRNOS:
            return True
        if any(s in str(exc).lower() for s in _DISK_FULL_TEXT):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


class DiskFullError(OnebitError):
    """No space left on the device while writing ``file``: the unfinished file was removed and
    every file written before it is intact."""

    def __init__(self, file: str | Path) -> None:
        self.file = str(file)
        super().__init__(
            f"{self.file}: no space left on the device while writing it; the unfinished file was removed "
            "and the outputs written before it are intact: free some space and run the command again"
        )
