"""Progress of long work: one line per stage, and bars that show only on a terminal.

The library never prints. A stage (:func:`stage`) is two records on the
``twin.progress`` logger at INFO, when it starts and when it ends with its
wall time; the ``twin`` command shows them on stderr unless ``--quiet``
(:func:`show_stages`), and a Python user sees them with
``logging.basicConfig(level=logging.INFO)``. Bars (:func:`bar`) are tqdm's,
drawn on stderr when the caller asks for progress and stderr is a terminal
(``disable=None``): piped into a file or a CI log they stay silent.
"""

from __future__ import annotations

import logging
import importlib.util
import sys
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

# In Jupyter, tqdm.auto draws widget bars, which need ipywidgets; without it, it warns at import (in every
# notebook that uses twin) and falls back to text bars: take the text bars directly then.
if importlib.util.find_spec("ipywidgets") is not None:
    from tqdm.auto import tqdm
else:
    from tqdm import tqdm

log = logging.getLogger("twin.progress")
#: Whether bars may be drawn at all (the command line's ``--quiet`` turns them off).
_bars = {"allowed": True}


def bar(iterable: Iterable | None = None, *, progress: bool = True, **kwargs: Any) -> tqdm:
    """A tqdm bar, drawn only when ``progress`` is asked for and stderr is a terminal.

    Examples
    --------
    >>> sum(bar(range(3), progress=False))
    3
    """
    return tqdm(iterable, disable=None if progress and _bars["allowed"] else True, **kwargs)


@contextmanager
def stage(name: str, timings: dict[str, float] | None = None) -> Iterator[None]:
    """Log the start and the end (with its wall time [s]) of a stage; record the time in ``timings``.

    Examples
    --------
    >>> times = {}
    >>> with stage("nothing much", times):
    ...     pass
    >>> list(times)
    ['nothing much']
    """
    log.info("%s ...", name)
    t0 = time.perf_counter()
    yield
    elapsed = time.perf_counter() - t0
    if timings is not None:
        timings[name] = elapsed
    log.info("%s: done in %.1f s", name, elapsed)


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is when a record comes (a host may swap it, as pytest does)."""

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr  # (not setStream: it would flush the old stream, which may be closed)
        super().emit(record)


def show_stages(enabled: bool | None = True) -> None:
    """The command line's display: stage lines on stderr as ``twin: <stage> ...`` and bars, or neither.

    Idempotent; ``enabled=False`` (``--quiet``) removes the lines and turns
    the bars off; ``None`` restores the library's default (no lines of its
    own, bars where the caller asks for them).
    """
    for h in [h for h in log.handlers if isinstance(h, _StderrHandler)]:
        log.removeHandler(h)
    _bars["allowed"] = enabled is not False
    if not enabled:
        log.propagate = True
        log.setLevel(logging.NOTSET)
        return
    handler = _StderrHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("twin: %(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    log.propagate = False
