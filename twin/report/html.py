"""A Markdown report as one self-contained HTML page: the figures embedded, a readable style, no other file.

Python-Markdown (with its ``tables`` and ``fenced_code`` extensions) turns
the report into HTML; each ``<img src="figure.png">`` naming a file beside
the report is replaced by the file's bytes as a ``data:`` URI, so the page
can be mailed or archived alone.
"""

from __future__ import annotations

import base64
import html
import mimetypes
import re
from pathlib import Path

from twin.errors import TwinError
from twin.netcdf import atomic_output

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 72rem; margin: 2rem auto;
       padding: 0 1.5rem; line-height: 1.45; color: #1b1b1b; }
h1, h2 { border-bottom: 1px solid #ddd; padding-bottom: .2rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .9rem; }
th, td { border: 1px solid #ccc; padding: .25rem .6rem; text-align: right; }
th { background: #f3f3f3; }
td:first-child, th:first-child { text-align: left; }
img { max-width: 100%; height: auto; display: block; margin: .6rem 0; }
code, pre { background: #f6f6f6; font-size: .88rem; }
pre { padding: .6rem; overflow-x: auto; }
"""


def _embed(match: re.Match, folder: Path) -> str:
    src = html.unescape(match.group(2))
    path = folder / src
    if "://" in src or src.startswith("data:"):
        return match.group(0)
    if not path.is_file():
        raise TwinError(f"{folder}: the report shows '{src}', which is not there")
    mime = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'{match.group(1)}"data:{mime};base64,{data}"'


def markdown_to_html(text: str, folder: str | Path, title: str) -> str:
    """The HTML page of Markdown ``text`` whose images are files in ``folder``, embedded.

    Examples
    --------
    >>> page = markdown_to_html("# Report\\n\\n| a | b |\\n| --- | --- |\\n| 1 | 2 |\\n", ".", "report")
    >>> "<table>" in page and "<h1>Report</h1>" in page
    True
    """
    import markdown

    body = markdown.markdown(text, extensions=["tables", "fenced_code"], output_format="html")
    body = re.sub(r'(<img[^>]*?src=)"([^"]+)"', lambda m: _embed(m, Path(folder)), body)
    return (
        f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{html.escape(title)}</title>\n'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">\n<style>{STYLE}</style>\n</head>\n'
        f"<body>\n{body}\n</body>\n</html>\n"
    )


def write_html_report(markdown_path: str | Path, title: str | None = None) -> Path:
    """Write ``report.html`` beside ``report.md`` (figures embedded), atomically; returns its path.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "report.md").write_text("# twin demo\\n\\nNothing hidden.\\n")
    ...     write_html_report(Path(tmp) / "report.md").name
    'report.html'
    """
    source = Path(markdown_path)
    try:
        text = source.read_text(encoding="utf-8")
    except OSError as exc:
        raise TwinError(f"{source}: cannot read the report ({exc.strerror})") from None
    page = markdown_to_html(text, source.parent, title or source.stem)
    target = source.with_suffix(".html")
    with atomic_output(target, ".html.part") as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target
