"""Exceptions raised by twin for bad input.

Every error says what is wrong and where (file, table, key, channel), so a user
never has to read a traceback from inside numpy to find the cause.
"""

from __future__ import annotations


class TwinError(Exception):
    """Base class of all errors twin raises on purpose."""


class ModelFileError(TwinError, ValueError):
    """A model or truth file is malformed.

    The message names the file, the table and the key.

    Examples
    --------
    >>> from twin import ModelFileError
    >>> err = ModelFileError("unit.toml", "[[bearing]] 'UGB'", "kxx", "missing key")
    >>> str(err)
    "unit.toml: [[bearing]] 'UGB': key 'kxx': missing key"
    """

    def __init__(self, path: str, table: str, key: str | None, problem: str) -> None:
        self.path, self.table, self.key, self.problem = str(path), table, key, problem
        where = f"{self.path}: {table}"
        if key is not None:
            where += f": key '{key}'"
        super().__init__(f"{where}: {problem}")


class ModelError(TwinError, ValueError):
    """A model built in Python is inconsistent (unknown node, parameter, ...)."""


class SignalError(TwinError, ValueError):
    """A signals file or record cannot be used (missing variable, NaN samples, dead channel, ...).

    The message names the file (or record) and the channel.
    """


class NoModeError(SignalError):
    """A record was read and analysed, but no physical mode stood out of it.

    Unlike the other signal errors the input is not wrong: a record too noisy or too short for any of its
    modes. A program that goes over many records (a benchmark, a campaign) can count it as a record with
    no mode and go on. ``block_rows`` is the number of block rows the analysis used.
    """

    def __init__(self, message: str, block_rows: int | None = None) -> None:
        super().__init__(message)
        self.block_rows = block_rows


class CompareError(TwinError, ValueError):
    """Measured modes that cannot be compared with a model (missing variables, too few samples, unknown channels)."""


class UpdateError(TwinError, ValueError):
    """The updating problem cannot be set up or solved as asked."""


class TwinWarning(UserWarning):
    """Something in the input is suspicious but usable (a clipped channel, a short record, ...)."""
