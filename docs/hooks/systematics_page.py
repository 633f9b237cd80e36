"""MkDocs hook: the error-budget table of the ``systematics`` study, rendered from its JSON.

``rollfric sweep systematics --out OUT`` then ``python -m validation.studies.systematics OUT --json
docs/data/systematics.json``; the next build shows it. The marker
``<!-- systematics-table -->`` in ``docs/lab-validation.md`` is replaced by
:func:`validation.studies.systematics.render_markdown` of that JSON (the table is computed, not
typed);
``<!-- thesis-error-table -->`` by :func:`validation.studies.thesis_error.render_markdown` of
``docs/data/thesis_error.json`` (``python -m validation.studies.thesis_error``).
"""

from __future__ import annotations

import json
from pathlib import Path

from validation.studies import thesis_error
from validation.studies.systematics import render_markdown

MARKER = "<!-- systematics-table -->"
THESIS_MARKER = "<!-- thesis-error-table -->"
PAGE = "lab-validation.md"
JSON = Path("data") / "systematics.json"
THESIS_JSON = Path("data") / "thesis_error.json"


def on_page_markdown(markdown, page, config, files):
    """Replace the marker of the lab-validation page with the study's error-budget table."""
    if page.file.src_uri != PAGE:
        return markdown
    docs = Path(config["docs_dir"])
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, render_markdown(json.loads((docs / JSON).read_text())))
    if THESIS_MARKER in markdown:
        markdown = markdown.replace(THESIS_MARKER, thesis_error.render_markdown(
            json.loads((docs / THESIS_JSON).read_text())))
    return markdown
