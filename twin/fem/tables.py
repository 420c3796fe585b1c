"""Reading TOML tables with errors that name the file, the table and the key.

The model, truth and schedule files share one reader: :class:`Table` wraps a parsed table with typed
getters (numbers, strings, names, nodes, arrays) that report any problem as a
:class:`~twin.errors.ModelFileError`, and a check for keys nobody read (typos, with the closest known key).
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.errors import ModelFileError

MISSING = object()
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_\-]*$")


class Table:
    """One TOML table being read: typed getters that report file/table/key, and a check for unknown keys."""

    def __init__(self, path: str, where: str, data: Any, section: Any = None) -> None:
        if not isinstance(data, Mapping):
            raise ModelFileError(path, where, None, f"must be a table, got {type(data).__name__}")
        self.path, self.where, self.data, self.section = path, where, data, section
        self.used: set[str] = set()

    def read(self, name: str, n_nodes: int | None = None) -> Any:
        """The value of key ``name`` as the table's section declares it (:class:`twin.fem.schema.Key`: its kind,
        default and rule); ``n_nodes`` bounds a node number."""
        key = self.section.key(name)
        if key.kind == "number":
            return self.number(
                name, key.default, positive=key.rule == "positive", nonnegative=key.rule == "nonnegative"
            )
        if key.kind == "node":
            return self.node(name, n_nodes)
        if key.kind == "name":
            return self.name(name)
        getter = {"string": self.string, "boolean": self.boolean, "array": self.array, "table": self._get}
        return getter[key.kind](name, key.default)

    def error(self, key: str | None, problem: str) -> ModelFileError:
        return ModelFileError(self.path, self.where, key, problem)

    def _get(self, key: str, default: Any) -> Any:
        self.used.add(key)
        if key not in self.data:
            if default is MISSING:
                close = difflib.get_close_matches(key, [k for k in self.data if isinstance(k, str)], n=1)
                hint = f" (the table has '{close[0]}': a typo?)" if close else ""
                raise self.error(key, f"missing key{hint}")
            return default
        return self.data[key]

    def has(self, key: str) -> bool:
        return key in self.data

    def number(self, key: str, default: Any = MISSING, *, positive: bool = False, nonnegative: bool = False) -> float:
        if key not in self.data and default is not MISSING:
            self.used.add(key)
            return default
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value}")
        if positive and value <= 0:
            raise self.error(key, f"must be positive, got {value:g}")
        if nonnegative and value < 0:
            raise self.error(key, f"must not be negative, got {value:g}")
        return value

    def integer(self, key: str, default: Any = MISSING) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected a whole number, got {value!r}")
        return value

    def string(self, key: str, default: Any = MISSING) -> str:
        value = self._get(key, default)
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {value!r}")
        return value

    def name(self, key: str = "name") -> str:
        value = self.string(key)
        if not NAME.match(value):
            raise self.error(
                key, f"{value!r} is not a valid name (letters, digits, '_' or '-', starting with a letter)"
            )
        return value

    def boolean(self, key: str, default: Any = MISSING) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {value!r}")
        return value

    def array(self, key: str, default: Any = MISSING) -> list:
        value = self._get(key, default)
        if not isinstance(value, list):
            raise self.error(key, f"expected an array, got {value!r}")
        return value

    def node_list(self, key: str, n_nodes: int, default: Any = MISSING) -> list[int]:
        nodes = self.array(key, default)
        for n in nodes:
            self._check_node(key, n, n_nodes)
        return nodes

    def node(self, key: str, n_nodes: int) -> int:
        n = self._get(key, MISSING)
        self._check_node(key, n, n_nodes)
        return n

    def _check_node(self, key: str, n: Any, n_nodes: int) -> None:
        if isinstance(n, bool) or not isinstance(n, int):
            raise self.error(key, f"expected a node number, got {n!r}")
        if not 0 <= n < n_nodes:
            raise self.error(key, f"node {n} does not exist (the shaft has nodes 0..{n_nodes - 1})")

    def finish(self) -> None:
        """Reject keys nobody read (typos), suggesting the closest known key."""
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            key = unknown[0]
            close = difflib.get_close_matches(key, sorted(self.used), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known keys: {', '.join(sorted(self.used))}"
            raise self.error(key, f"unknown key{hint}")


def array_of_tables(top: Table, key: str, required: bool = False, section: Any = None) -> list[Table]:
    """The tables of the array ``[[key]]``, each named by its place (``[[key]] #1``), read as ``section`` declares."""
    items = top.array(key, MISSING if required else [])
    if required and not items:
        raise top.error(key, f"at least one [[{key}]] table is needed")
    return [Table(top.path, f"[[{key}]] #{i + 1}", item, section) for i, item in enumerate(items)]


def label_table(table: Table, name: str) -> None:
    """Name the table by its element: ``[[bearing]] #2`` becomes ``[[bearing]] 'UGB'``."""
    table.where = f"{table.where.split(' ')[0]} '{name}'"


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file, reporting a missing, unreadable or malformed file as a ModelFileError."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ModelFileError(str(path), "(file)", None, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(str(path), "(file)", None, f"cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ModelFileError(str(path), "(file)", None, f"not valid TOML: {exc}") from None
