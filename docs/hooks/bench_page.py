"""MkDocs hook: the benchmark tables of ``docs/benchmarks.md``, rendered from ``bench.json``.

``rollfric bench --out DIR`` writes ``DIR/bench.json``; copy it to ``docs/data/bench.json`` and
the next build shows it. The marker ``<!-- bench-tables -->`` in the page is replaced by: the
run's date, machine and provenance, one table per section (value, baseline, gain, note) and,
for the recognition section, a matrix of centre errors (case x locator).
"""

from __future__ import annotations

import json
from pathlib import Path

from validation.bench_table import fmt  # the bench's own number format

MARKER = "<!-- bench-tables -->"
PAGE = "benchmarks.md"
JSON = Path("data") / "bench.json"




def fmt_px(v) -> str:
    """A centre error in px to 3 significant figures, without an exponent."""
    return fmt(v) if not fmt(v) else f"{v:.3g}"


def _cell(s: str) -> str:
    return str(s).replace("|", "\\|")


def section_table(rows: list[dict]) -> list[str]:
    """One section's rows as a Markdown table."""
    out = ["| measured | value | baseline | baseline value | gain | note |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        gain = f"{fmt(r.get('gain'))}x {r.get('gain_kind', '')}" if fmt(r.get("gain")) else ""
        out.append(f"| {_cell(r['item'])} | {fmt(r['value'])} {r.get('unit', '')} | "
                   f"{_cell(r.get('baseline', ''))} | {fmt(r.get('baseline_value'))} | {gain} | "
                   f"{_cell(r.get('note', ''))} |")
    return out


def recognition_matrix(rows: list[dict]) -> list[str]:
    """Centre rms error (px) per case and locator, from the ``subpixel ...`` rows."""
    cases: dict[str, dict[str, str]] = {}
    cols = ["subpixel (default)", "Cramer-Rao bound"]
    for r in rows:
        case, sep, what = r["item"].partition(": ")
        if not sep:
            continue
        c = cases.setdefault(case, {})
        if what == "subpixel centre rms":
            c["subpixel (default)"] = fmt_px(r["value"])
            c["Cramer-Rao bound"] = fmt_px(r.get("baseline_value"))
        elif what.startswith("subpixel vs "):
            name = r.get("baseline") or what[len("subpixel vs "):]
            if name not in cols:
                cols.append(name)
            v = fmt_px(r.get("baseline_value"))
            found = [p for p in str(r.get("note", "")).split("; ") if "found" in p]
            pct = found[0].rsplit("found", 1)[1].strip() if found else ""
            if not v:
                v = "none found"
            elif pct and pct != "100 %":
                v += f" ({pct} found)"
            c[name] = v
    if not cases:
        return []
    out = ["| case (centre rms, px) | " + " | ".join(cols) + " |",
           "|---" * (len(cols) + 1) + "|"]
    for case, c in cases.items():
        out.append(f"| {case} | " + " | ".join(c.get(k, "") for k in cols) + " |")
    return out


STAGE = "lean tile frame: "


def stage_table(rows: list[dict]) -> list[str]:
    """Where a lean tile frame's time goes: one line per stage row, its ms and share."""
    stages = [r for r in rows if r["item"].startswith(STAGE)]
    total = sum(float(r["value"]) for r in stages)
    if not stages or total <= 0:
        return []
    out = ["| a lean tile frame's stage | ms | share |", "|---|---|---|"]
    for r in stages:
        out.append(f"| {_cell(r['item'][len(STAGE):])} | {fmt(r['value'])} | "
                   f"{100 * float(r['value']) / total:.0f} % |")
    return out + [f"| all stages | {fmt(total)} | 100 % |"]


def render(data: dict) -> str:
    """The Markdown that replaces the marker."""
    meta = data.get("meta", {})
    m = meta.get("machine", {})
    lines = [f"**Run:** {meta.get('date', 'unknown date')}, {m.get('cpu', 'unknown CPU')}, "
             f"{m.get('cores', '?')} cores, Python {m.get('python', '?')}"
             + (", `--quick`" if meta.get("quick") else ", full run") + "."]
    if meta.get("source"):
        lines += ["", f"**Provenance:** {meta['source']}"]
    secs = meta.get("section_seconds") or {}
    if secs:
        lines += ["", "Section wall times: " + ", ".join(f"{k} {v:.0f} s" for k, v in secs.items())
                  + "."]
    by_section: dict[str, list[dict]] = {}
    for r in data.get("rows", []):
        by_section.setdefault(r["section"], []).append(r)
    for name, rows in by_section.items():
        lines += ["", f"## {name.capitalize()}", ""]
        if name == "rendering" and stage_table(rows):
            lines += section_table([r for r in rows if not r["item"].startswith(STAGE)])
            lines += ["", "Where a tile frame's time goes (lean path, each stage waited for):",
                      ""] + stage_table(rows)
        elif name == "recognition":
            matrix = recognition_matrix(rows)
            if matrix:
                lines += matrix + [""]
            rest = [r for r in rows if ": subpixel" not in r["item"]]
            if rest:
                lines += section_table(rest)
        else:
            lines += section_table(rows)
    return "\n".join(lines) + "\n"


def on_page_markdown(markdown, page, config, files):
    """Replace the marker of the benchmarks page with the tables of ``bench.json``."""
    if page.file.src_uri != PAGE or MARKER not in markdown:
        return markdown
    path = Path(config["docs_dir"]) / JSON
    data = json.loads(path.read_text())
    return markdown.replace(MARKER, render(data))
