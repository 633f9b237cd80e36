"""MkDocs hook: the API reference of rollfric's public names, generated at build time.

The public API is ``rollfric.__all__``; each name gets a mkdocstrings directive on the page of
its concept (the module that defines it), so a name that is added to ``__all__`` appears in
the reference without editing ``mkdocs.yml``, and internals never do.
"""

from __future__ import annotations

from mkdocs.structure.files import File

SECTION = "API reference"
# the module that defines a name -> the page it is listed on
TITLES = {
    "rollfric.measurement": "Measuring",
    "rollfric.track.tracker": "Measuring",
    "rollfric.track.track_info": "Measuring",
    "rollfric.geometry.theta": "Measuring",
    "rollfric.io.readers": "Recordings",
    "rollfric.io.source": "Recordings",
    "rollfric.setup.model": "Setup and calibration",
    "rollfric.setup.lens": "Setup and calibration",
    "rollfric.fit.estimate": "Fitting mu",
    "rollfric.fit.result": "Fitting mu",
    "rollfric.uncertainty.measured": "Uncertainty",
    "rollfric.uncertainty.budget": "Uncertainty",
    "rollfric.errors": "Errors",
}


def _pages() -> dict[str, list[str]]:
    """Page title -> the dotted paths of the public names it documents, in __all__'s order of
    definition."""
    import rollfric

    pages: dict[str, list[str]] = {}
    for name in rollfric.__all__:
        module = getattr(rollfric, name).__module__
        pages.setdefault(TITLES.get(module, module), []).append(f"{module}.{name}")
    return pages


def _slug(title: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in title.lower()).strip("-")


def on_config(config):
    """Append one page a concept to the ``API reference`` section of ``nav``."""
    pages = _pages()
    config["extra"]["api_pages"] = pages
    for item in config["nav"] or []:
        if isinstance(item, dict) and SECTION in item:
            item[SECTION].extend({title: f"api/{_slug(title)}.md"} for title in pages)
    return config


def on_files(files, config):
    """Add the pages in memory: a title and one mkdocstrings directive a public name."""
    for title, paths in config["extra"]["api_pages"].items():
        body = "\n\n".join(f"::: {p}\n    options:\n      heading_level: 2" for p in paths)
        files.append(File.generated(config, f"api/{_slug(title)}.md",
                                    content=f"# {title}\n\n{body}\n"))
    return files
