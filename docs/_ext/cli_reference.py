"""The ``twin`` parser as the docs' command-line page renders it.

sphinx-argparse parses every help string and description as reStructuredText,
so a glob such as ``*.nc`` in a help string opens an emphasis that never closes
and the build fails under ``-W``. The terminal shows those strings as written;
here each character that reStructuredText reads as markup is escaped, so any
help string renders as the terminal prints it.
"""

from __future__ import annotations

import argparse
import re

from twin.cli.parser import build_parser as _build_parser

#: Characters that open or close inline markup, references or substitutions in reStructuredText.
_MARKUP = re.compile(r"([\\*`|_\[\]<>])")


def escape(text: str) -> str:
    """``text`` with every reStructuredText markup character backslash-escaped."""
    return _MARKUP.sub(r"\\\1", text)


def _escape_parser(parser: argparse.ArgumentParser) -> None:
    if parser.description:
        parser.description = escape(parser.description)
    if parser.epilog:
        parser.epilog = escape(parser.epilog)
    for action in parser._actions:
        if action.help and action.help is not argparse.SUPPRESS:
            action.help = escape(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.help:
                    choice.help = escape(choice.help)
            for sub in dict.fromkeys(action.choices.values()):
                _escape_parser(sub)


def build_parser() -> argparse.ArgumentParser:
    """``twin``'s parser with its help strings and descriptions escaped for reStructuredText."""
    parser = _build_parser()
    _escape_parser(parser)
    return parser
