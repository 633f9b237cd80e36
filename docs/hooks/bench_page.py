"""MkDocs hook: the benchmark tables of ``docs/benchmarks.md``, rendered from ``bench.json``.

``rollfric bench --out DIR`` writes ``DIR/bench.json``; copy it to ``docs/data/bench.json`` and
the next build shows it. The marker ``<!-- bench-tables -->`` in the page is replaced by: the
run's date, machine and provenance, one table per section (value, baseline, gain, note) and,
for the recognition section, a matrix of centre errors (case x locator). The marker
``<!-- bench-figure -->`` (under the page's title) is replaced by a figure of the headline
ratios with their spread, drawn from the same JSON at build time (``img/bench/ratios.svg``, a
generated file: nothing is committed that could go stale).
"""

from __future__ import annotations

import io
import json
import re
import statistics
from pathlib import Path

from validation.bench.table import fmt  # the bench's own number format

MARKER = "<!-- bench-tables -->"
PAGE = "benchmarks.md"
JSON = Path("data") / "bench.json"
FIGURE_MARKER = "<!-- bench-figure -->"
FIGURE = "img/bench/ratios.svg"




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


# -- the headline figure ------------------------------------------------------------------------

# (label, section, how the item starts, what its rows are): each group's rows are one line of
# the figure, its spread over the rows (balls, engines, clusters) or over the repeated runs a
# row's note lists
HEADLINES = (
    ("fit: lsq vs the thesis's grid search", "fitting", "lsq fit time", "balls"),
    ("simulate 4 s: the reference ODE vs real time", "simulation", "reference ODE", "runs"),
    ("simulate: tangent contact vs the mesh", "simulation",
     ("mujoco tangent contact: 4 s", "pybullet tangent contact: 4 s"), "engines"),
    ("render a tile frame vs stock pyrender's full frame", "rendering",
     "tile frame, synth's lean draw path", "runs"),
    ("render a recording (2 processes) vs stock pyrender", "rendering", "sequence of", "runs"),
    ("locate: the streaming loop vs 1000 frames/s", "recognition", "streaming loop", "runs"),
    ("measure end to end vs 1000 frames/s", "end-to-end",
     "measure a synth recording end to end", "runs"),
    ("validate 4001 frames vs 4001 stock pyrender frames", "end-to-end", "total", "runs"),
    ("sweep on 2 workers vs one case after another", "sweeps", "", "clusters"),
)
_REPEATS = re.compile(r"in order ((?:[\d.]+x\s*/\s*)+[\d.]+x)")
_TARGET = re.compile(r"target >= ([\d.]+)x")


def _number(v) -> float | None:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if v == v and v > 0 else None


def headline_ratios(data: dict) -> list[dict]:
    """The headline speed ratios of a bench run, one dict per group found.

    Parameters
    ----------
    data : dict
        bench.json's content.

    Returns
    -------
    list of dict
        ``{"label", "value", "values", "over", "target"}``: the median ratio, every ratio it is the
        median of (one per matching row; a row whose note lists its repeated runs, ``in order
        94.3x / 107.6x / 108.2x``, gives those instead), what they are (``balls``, ``runs``,
        ...), and the target ratio a note or a
        ``target ...`` baseline states (None without one). Groups without a row are left out.
    """
    out = []
    for label, section, start, over in HEADLINES:
        starts = (start,) if isinstance(start, str) else start
        values, target = [], None
        for r in data.get("rows", []):
            item = str(r.get("item", ""))
            if r.get("section") != section or not any(item.startswith(s) for s in starts):
                continue
            if start == "total" and item != "total":
                continue
            gain = _number(r.get("gain"))
            if gain is None or "speed" not in str(r.get("gain_kind", "speed-up")):
                continue
            note = str(r.get("note", ""))
            rep = _REPEATS.search(note)
            if rep:
                over = "runs"
            values += ([float(v) for v in re.findall(r"([\d.]+)x", rep.group(1))] if rep
                       else [gain])
            t = _TARGET.search(note)
            if t:
                target = float(t.group(1))
            elif str(r.get("baseline", "")).startswith("target"):
                target = 1.0
        if values:
            out.append({"label": label, "value": statistics.median(values),
                        "values": sorted(values), "over": over, "target": target})
    return out


def ratio_figure(data: dict) -> bytes | None:
    """The headline ratios as an SVG figure (None when the run has none of them)."""
    rows = headline_ratios(data)
    if not rows:
        return None
    import matplotlib
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 0.42 * len(rows) + 1.3), layout="constrained")
    ax = fig.subplots()
    for i, r in enumerate(rows):
        v = r["values"]
        ax.plot([v[0], v[-1]], [i, i], color="C0", lw=2.5, alpha=0.45, solid_capstyle="round")
        ax.plot(v, [i] * len(v), "|", color="C0", ms=9)
        ax.plot(r["value"], i, "o", color="C0", ms=6)
        text = (f"{fmt(r['value'])}x" if len(v) == 1
                else f"{fmt(r['value'])}x ({fmt(v[0])}-{fmt(v[-1])} over {len(v)} {r['over']})")
        ax.annotate(text, (v[-1], i), xytext=(8, 0), textcoords="offset points", va="center",
                    fontsize=8)
        if r["target"]:
            ax.plot(r["target"], i, marker="|", ls="none", color="C3", ms=16, mew=2,
                    label="the target" if i == min(j for j, q in enumerate(rows) if q["target"])
                    else None)
    ax.axvline(1, color="0.5", lw=0.8)
    ax.set_xscale("log")
    lo = min(min(r["values"]) for r in rows)
    hi = max(max(r["values"]) for r in rows)
    ax.set_xlim(min(0.5, lo / 1.5), hi * 12)
    ax.set_yticks(range(len(rows)), [r["label"] for r in rows], fontsize=8)
    ax.invert_yaxis()
    ax.grid(axis="x", which="major", alpha=0.3)
    ax.set_xlabel("ratio over the baseline (x; > 1: faster)")
    if any(r["target"] for r in rows):
        ax.legend(fontsize=8, loc="lower right")
    meta = data.get("meta", {})
    ax.set_title(f"the bench's headline speed ratios ({meta.get('date', 'undated')}, "
                 f"{meta.get('machine', {}).get('cores', '?')} cores)\na dot: the median; "
                 "a bar: the spread over the balls, engines or runs measured", fontsize=9)
    buf = io.BytesIO()
    with matplotlib.rc_context({"svg.hashsalt": "rollfric-bench"}):  # the same file each build
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def _load(config) -> dict:
    return json.loads((Path(config["docs_dir"]) / JSON).read_text())


def on_files(files, config):
    """Add the headline figure, drawn from ``bench.json``, to the site's files."""
    from mkdocs.structure.files import File

    svg = ratio_figure(_load(config))
    if svg is not None:
        files.append(File.generated(config, FIGURE, content=svg))
    return files


def on_page_markdown(markdown, page, config, files):
    """Replace the markers of the benchmarks page with the figure and the tables of
    ``bench.json``."""
    if page.file.src_uri != PAGE or MARKER not in markdown:
        return markdown
    data = _load(config)
    if FIGURE_MARKER in markdown:
        rows = headline_ratios(data)
        image = ("![The bench's headline speed ratios: each stage against the baseline a user "
                 "would pick instead, the spread over balls, engines and repeated runs, and the "
                 f"target where the project set one]({FIGURE})") if rows else ""
        markdown = markdown.replace(FIGURE_MARKER, image)
    return markdown.replace(MARKER, render(data))
