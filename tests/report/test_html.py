"""The self-contained HTML report: figures embedded, checked in a real headless browser."""

import re
import shutil
import subprocess

import pytest

from twin.errors import TwinError
from twin.loop.history import history_dataset, plot_history
from twin.report.html import markdown_to_html, write_html_report

CHROMIUM = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


def _report(folder):
    plot_history(history_dataset(["start", "update"], [0.05, 0.001], [900.0, 19.0]), folder / "history.png")
    text = (
        "# twin demo\n\nThe error **fell**.\n\n| step | E [%] |\n| --- | --- |\n| 0 | 5.000 |\n| 1 | 0.100 |\n\n"
        "![history](history.png)\n"
    )
    (folder / "report.md").write_text(text)
    return write_html_report(folder / "report.md", title="twin demo")


def test_page_embeds_every_figure_and_needs_no_other_file(tmp_path):
    page = _report(tmp_path).read_text()
    assert page.startswith("<!DOCTYPE html>") and "<table>" in page and "<strong>fell</strong>" in page
    assert re.search(r'<img alt="history" src="data:image/png;base64,[A-Za-z0-9+/=]{1000,}"', page)
    assert "history.png" not in page.replace('alt="history"', "")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["history.png", "report.html", "report.md"]


def test_missing_figure_is_named_and_nothing_is_written(tmp_path):
    (tmp_path / "report.md").write_text("![mac](mac.png)\n")
    with pytest.raises(TwinError, match="shows 'mac.png', which is not there"):
        write_html_report(tmp_path / "report.md")
    assert not (tmp_path / "report.html").exists()
    assert "<h1>x</h1>" in markdown_to_html("# x", tmp_path, "t")


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine (Debian: apt-get install chromium)")
def test_page_renders_in_a_headless_browser(tmp_path):
    """Chromium loads the page alone (moved away from its figures): every image decodes, the table has its rows."""
    page = _report(tmp_path).read_text()
    probe = (
        "<script>window.addEventListener('load', () => { const imgs = [...document.images]; "
        "document.body.setAttribute('data-check', imgs.length + ' images, ' + "
        "imgs.filter(i => i.complete && i.naturalWidth > 100).length + ' decoded, ' + "
        "document.querySelectorAll('tr').length + ' rows'); });</script>"
    )
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "page.html").write_text(page.replace("</body>", probe + "</body>"))
    out = subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=5000",
            "--dump-dom",
            (alone / "page.html").as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert 'data-check="1 images, 1 decoded, 3 rows"' in out.stdout, out.stderr[-2000:]
