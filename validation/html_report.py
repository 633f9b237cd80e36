"""A self-contained HTML report: the verdict in words, the summary, then the figures, every
image embedded (base64), no script, no network; it opens from a file in any browser."""

from __future__ import annotations

import base64
import html
from pathlib import Path

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
.verdict { font-size: 1.15em; padding: 0.7em 1em; border-radius: 6px; margin: 1em 0; }
.good { background: #e6f4ea; border-left: 6px solid #1e8e3e; }
.bad { background: #fce8e6; border-left: 6px solid #d93025; }
pre { background: #f6f8fa; padding: 1em; overflow-x: auto; font-size: 0.85em; }
figure { margin: 2em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { color: #555; font-size: 0.95em; margin-top: 0.4em; }
table { border-collapse: collapse; font-size: 0.9em; }
td, th { border: 1px solid #ddd; padding: 0.3em 0.6em; text-align: right; }
"""


def _img(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(Path(path).name)}">'


def render(title: str, verdict: str, good: bool, summary: str,
           figures: list[tuple[Path, str]], table_html: str = "") -> str:
    """The page as text.

    Parameters
    ----------
    title : str
        The page's heading.
    verdict : str
        The answer in one or two plain sentences (shown first, green when ``good``, else red).
    good : bool
        Whether the verdict is the hoped-for one.
    summary : str
        The command's printed summary (shown as it is, monospaced).
    figures : list of (pathlib.Path, str)
        PNG files and the question each answers (its caption); missing files are skipped.
    table_html : str, optional
        An HTML table placed after the summary (already escaped).

    Returns
    -------
    str
        The HTML document.
    """
    figs = "\n".join(
        f"<figure>{_img(p)}<figcaption>{html.escape(caption)}</figcaption></figure>"
        for p, caption in figures if Path(p).is_file())
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>\n"
        f"<h1>{html.escape(title)}</h1>\n"
        f"<div class=\"verdict {'good' if good else 'bad'}\">{html.escape(verdict)}</div>\n"
        f"<pre>{html.escape(summary)}</pre>\n{table_html}\n{figs}\n</body></html>\n")
