"""The docs' generated figures: the Benchmarks page's headline figure (docs/hooks/bench_page.py,
drawn from bench.json at build time) and the page figures' architecture, drawn from the code's
imports (docs/scripts/page_figures.py)."""

import importlib.util
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module(path, name):
    spec = importlib.util.spec_from_file_location(name, ROOT / path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def hook():
    return _module("docs/hooks/bench_page.py", "docs_bench_page")


def _row(section, item, gain, **kw):
    return {"section": section, "item": item, "value": 1.0, "unit": "s", "gain": gain,
            "gain_kind": "speed-up", **kw}


DATA = {"meta": {"date": "2026-01-01 00:00 UTC", "machine": {"cores": 2}}, "rows": [
    _row("fitting", "lsq fit time (10mm)", 200.0),
    _row("fitting", "lsq fit time (12.69mm)", 240.0),
    _row("fitting", "lsq fit time (1.58mm)", 230.0),
    _row("fitting", "lsq mu error, 0.02 deg noise (10mm)", 25.0, gain_kind="accuracy"),
    _row("rendering", "sequence of 4000 frames", 110.5, note="255 frames/s; target >= 100x"),
    _row("end-to-end", "total", 107.6,
         note="the median of 3 runs of the case, in order 94.3x / 107.6x / 108.2x (totals "
              "17.7 / 15.6 / 15.4 s); target >= 100x"),
    _row("end-to-end", "total stock", 5.0),
    _row("end-to-end", "measure a synth recording end to end (frames/s)", 1.59,
         baseline="target 1000 frames/s"),
]}


def test_headline_ratios_take_the_median_and_spread_of_rows_and_repeated_runs(hook):
    rows = {r["label"].split(":")[0].split(" ")[0]: r for r in hook.headline_ratios(DATA)}
    assert set(rows) == {"fit", "render", "measure", "validate"}
    fit = rows["fit"]  # the three balls, the accuracy row left out
    assert fit["values"] == [200.0, 230.0, 240.0] and fit["value"] == 230.0
    assert fit["target"] is None and fit["over"] == "balls"
    val = rows["validate"]  # the note's three runs, not the row's median alone
    assert val["values"] == [94.3, 107.6, 108.2] and val["value"] == 107.6
    assert val["over"] == "runs"
    assert val["target"] == 100.0
    assert rows["render"]["target"] == 100.0 and rows["render"]["values"] == [110.5]
    assert rows["measure"]["target"] == 1.0


def test_the_benchmarks_page_opens_with_the_figure_drawn_from_its_json(hook, tmp_path):
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "bench.json").write_text(json.dumps(DATA))
    config = {"docs_dir": str(tmp_path)}
    page = SimpleNamespace(file=SimpleNamespace(src_uri="benchmarks.md"))
    md = hook.on_page_markdown("# Benchmarks\n\n<!-- bench-figure -->\n\n<!-- bench-tables -->\n",
                               page, config, None)
    assert f"]({hook.FIGURE})" in md.split("## ")[0] and "<!--" not in md
    svg = hook.ratio_figure(DATA)
    assert svg.startswith(b"<?xml") and b"<svg" in svg
    assert hook.ratio_figure(DATA) == svg  # the same bytes on every build
    # a run without any headline row: no figure, no broken image
    empty = {"rows": [_row("fitting", "something else", 2.0)]}
    (tmp_path / "data" / "bench.json").write_text(json.dumps(empty))
    md = hook.on_page_markdown("# B\n\n<!-- bench-figure -->\n\n<!-- bench-tables -->\n", page,
                               config, None)
    assert "![" not in md and hook.ratio_figure(empty) is None


def test_the_shipped_bench_has_the_headline_ratios(hook):
    data = json.loads((ROOT / "docs" / "data" / "bench.json").read_text())
    rows = hook.headline_ratios(data)
    assert len(rows) >= 6, [r["label"] for r in rows]
    assert all(min(r["values"]) <= r["value"] <= max(r["values"]) for r in rows)


def test_the_architecture_figure_draws_the_imports_the_code_has():
    pf = _module("docs/scripts/page_figures.py", "docs_page_figures")
    edges = pf.import_edges()
    # the layering docs/how/architecture.md states: rollfric imports none of the others
    assert not {e for e in edges if e[0] == "rollfric"}
    assert {("sim", "rollfric"), ("synth", "sim"), ("synth", "rollfric"),
            ("validation", "rollfric"), ("validation", "sim"), ("validation", "synth")} == edges
