"""MkDocs hook: one API reference page per public module, generated at build time.

The modules are found by walking the packages' source folders (no import), so a module that is
added, renamed or split into a package appears in the reference without editing ``mkdocs.yml``.
Each page holds one mkdocstrings directive (``::: package.module``); the pages are appended to
the ``API reference`` section of ``nav``, measurement first, then the validation suite.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File

GROUPS = {
    "rollfric (the measurement)": ["rollfric"],
    "Validation suite": ["sim", "synth", "validation"],
}
SECTION = "API reference"


def _modules(root: Path, package: str) -> list[str]:
    """Dotted names of ``package`` and its public submodules, in path order."""
    base = root / package
    if not (base / "__init__.py").is_file():
        return []
    names = []
    for path in sorted(base.rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts) or parts[-1] == "__main__":
            continue
        if not all((root / Path(*parts[:i]) / "__init__.py").is_file()
                   for i in range(1, len(parts))):
            continue  # a folder of scripts, not a subpackage
        names.append(".".join(parts))
    return names


def _pages(config) -> dict[str, list[str]]:
    root = Path(config["config_file_path"]).parent
    return {group: [m for p in pkgs for m in _modules(root, p)] for group, pkgs in GROUPS.items()}


def on_config(config):
    """Append the generated pages to the ``API reference`` section of ``nav``."""
    groups = _pages(config)
    config["extra"]["api_modules"] = groups
    for item in config["nav"] or []:
        if isinstance(item, dict) and SECTION in item:
            entries = item[SECTION]
            for group, mods in groups.items():
                entries.append({group: [{m: f"api/{m}.md"} for m in mods]})
    return config


def on_files(files, config):
    """Add one in-memory page per module: its title and the mkdocstrings directive."""
    for mods in config["extra"]["api_modules"].values():
        for m in mods:
            files.append(File.generated(config, f"api/{m}.md",
                                        content=f"# `{m}`\n\n::: {m}\n    options:\n"
                                                f"      show_root_heading: false\n"))
    return files
