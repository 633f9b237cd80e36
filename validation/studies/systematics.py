"""The error budget of the ``systematics`` study: what each lab error source does to mu.

``rollfric sweep systematics --out OUT`` runs each source alone over its range (blind mode);
``python -m validation.studies.systematics OUT --json docs/data/systematics.json`` turns its results
into the study's JSON (one row a case: the source, its magnitude, whether rollfric's correction
was on, how the case was run, mu bias, the thesis's relative error, theta rms), and
:func:`budget_table` / :func:`render_markdown` turn that JSON into the docs' error-budget table
(the docs hook ``docs/hooks/systematics_page.py``): for each source and correction, the
magnitude that biases mu by 0.1 % and by 1 %, interpolated linearly between the swept
magnitudes (from no error, no bias, where magnitude 0 means no error).

A case's source is the first of :data:`SOURCES` that recognises its parameters; a case no
source recognises (a source added to the sweep file by someone else) is its own source, named
after its swept keys, its magnitude the first number among their values.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

from rollfric.output.atomic import write_text
from validation.sweep import load_sweep

LEVELS = (0.001, 0.01)  # |mu bias| of the table's columns: 0.1 % and 1 %
# swept keys that say how a case was measured, not which error it has
CORRECTION_KEYS = ("measure.offset", "lab.lens_calibrated", "lab.camera.matrix",
                   "lab.camera.distortion", "measure.oracle", "render.seed", "stages")


def _num(v):
    """A number from a table cell (None, NaN, bool and text are None)."""
    if isinstance(v, bool) or v is None:
        return None
    if isinstance(v, str):
        try:
            v = json.loads(v)
        except ValueError:
            return None
        return _num(v) if not isinstance(v, list) else None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _list(v):
    if isinstance(v, str):
        try:
            v = json.loads(v)
        except ValueError:
            return None
    return list(v) if isinstance(v, (list, tuple)) else None


def _offset_on(row) -> bool:
    v = row.get("measure.offset")
    return not (v is False or v == "false" or v == "False")


@dataclasses.dataclass(frozen=True)
class Source:
    """One error source of the study.

    Attributes
    ----------
    name : str
        What the table calls it.
    unit : str
        The magnitude's unit.
    magnitude : callable
        row (dict: the sweep's parameters and metrics) -> the source's magnitude, or None when
        the case is not this source's.
    typical : str
        A lab's range and where it comes from.
    corrected : callable or None
        row -> whether rollfric's correction of this source was on; None: rollfric has none.
    origin : bool
        Magnitude 0 is no error (the interpolation starts from (0, 0)).
    """

    name: str
    unit: str
    magnitude: Callable
    typical: str
    corrected: Callable | None = None
    origin: bool = True


def _lab_err(col: str, scale: Callable = lambda e, row: -e):
    def f(row):
        e = _num(row.get(f"lab_err_{col}"))
        if e is None or e == 0.0:
            return None
        return scale(e, row)
    return f


def _rel(col: str, factor: float):
    def scale(e, row):
        nominal = _num(row.get(f"lab_{col}"))
        return -e / nominal * factor if nominal else None
    return scale


def _center(i: int):
    def f(row):
        v = _list(row.get("lab.center_error_px"))
        if v is None or len(v) != 2 or v[i] == 0 or v[1 - i] != 0:
            return None
        return float(v[i])
    return f


def _key(key: str, index: int | None = None, when: Callable | None = None):
    def f(row):
        if when is not None and not when(row):
            return None
        v = row.get(key)
        if index is not None:
            v = _list(v)
            v = v[index] if v is not None and len(v) > index else None
        v = _num(v)
        return None if v is None or v == 0.0 else v
    return f


def _lens_calibrated(row) -> bool:
    v = row.get("lab.lens_calibrated")
    return v is True or v == "true" or v == "True" or row.get("lab.camera.matrix") is not None


def _aperture(at_ball: bool):
    """Defocus (render.camera.f_number): the aperture's diameter f / N (mm), for a case focused
    on the ball's plane (``at_ball``) or elsewhere (the trough's front face)."""
    def f(row):
        n = _num(row.get("render.camera.f_number"))
        if n is None:
            return None
        wd = (_num(row.get("render.camera.working_distance")) or 0.5) * 1000.0
        focus = _num(row.get("render.camera.focus_distance_mm"))
        if (focus is None or abs(focus - wd) < 0.01) != at_ball:
            return None
        return (_num(row.get("render.camera.focal_length_mm")) or 50.0) / n
    return f


SOURCES: tuple[Source, ...] = (
    Source("trough radius as built - nominal", "mm",
           _lab_err("cylinder_radius_mm"),
           "+-0.1 .. 0.3 mm: the bore of a machined block (the thesis gives 85.3 mm without a "
           "tolerance)"),
    Source("ball diameter as built - nominal", "mm", _lab_err("ball_diameter_mm"),
           "+-0.02 mm: a caliper reading (grade balls are better than 1 um)"),
    Source("pixel scale as built - nominal", "%",
           _lab_err("camera_pixel_size_mm", _rel("camera_pixel_size_mm", 100.0)),
           "+-0.5 %: a ruler in the ball's plane"),
    Source("frame rate as built - nominal", "ppm",
           _lab_err("camera_fps", _rel("camera_fps", 1e6)),
           "+-100 ppm: the camera's crystal"),
    Source("trough centre measured by the lab, x error", "px", _center(0),
           "+-1 .. 2 px by eye on the background (the thesis: within 1 px)", _offset_on),
    # the fitted offset does not touch a centre off along y (it scales the angles): no correction
    Source("trough centre measured by the lab, y error", "px", _center(1),
           "+-1 .. 2 px by eye on the background"),
    Source("camera roll", "deg", _key("render.camera.roll_deg"),
           "+-1 deg levelled by eye, +-0.1 .. 0.2 deg with a spirit level on the camera",
           _offset_on),
    Source("lens k1 at fx = 2400 px", "1",
           _key("render.camera.lens_distortion", 0),
           "-0.05 .. -0.2: C-mount lenses of 12 .. 25 mm", _lens_calibrated),
    Source("pinhole camera at working distance", "m",
           _key("render.camera.working_distance",
                when=lambda row: row.get("render.camera.projection") == "perspective"),
           "0.3 .. 1 m (the ball's plane 15 mm behind the trough's front face)",
           lambda row: _num(row.get("lab.camera.working_distance_mm")) is not None,
           origin=False),
    Source("camera pitch (optical axis tilted up or down)", "deg",
           _key("render.camera.pitch_deg"), "+-1 deg: a camera aligned by eye"),
    Source("camera yaw (optical axis tilted sideways)", "deg", _key("render.camera.yaw_deg"),
           "+-1 deg: a camera aligned by eye"),
    Source("trough out of round (D_max - D_min), major axis horizontal", "mm",
           _key("scenario.cylinder.ovality_mm",
                when=lambda row: (_num(row.get("scenario.cylinder.ovality_angle_deg"))
                                  or 0.0) == 0.0),
           "tens of um: a machined bore (rollfric fits the contour's ellipse and warns)"),
    Source("trough out of round (D_max - D_min), major axis vertical", "mm",
           _key("scenario.cylinder.ovality_mm",
                when=lambda row: _num(row.get("scenario.cylinder.ovality_angle_deg")) == 90.0),
           "tens of um: a machined bore (rollfric fits the contour's ellipse and warns)"),
    Source("trough axis tilted along its length", "deg", _key("scenario.cylinder.tilt_deg"),
           "0.01 .. 0.05 deg: levelled with a spirit level"),
    Source("frame-time jitter (standard deviation)", "us", _key("render.timing.jitter_us"),
           "below 1 us for a high-speed camera's clock; tens of us for a webcam"),
    Source("dropped frames (rate), found from the motion", "1",
           _key("render.timing.drop_rate",
                when=lambda row: row.get("render.timing.timestamps") not in (True, "true",
                                                                             "True")),
           "none in a high-speed camera's memory; a USB or capture path can drop frames"),
    Source("dropped frames (rate), the recording's timestamps", "1",
           _key("render.timing.drop_rate",
                when=lambda row: row.get("render.timing.timestamps") in (True, "true", "True")),
           "as above, in a format that keeps each frame's time (cine, Zarr)"),
    Source("MJPEG video, quality (100 = best)", "1",
           _key("render.video.quality", when=lambda row: row.get("render.video.codec") == "mjpeg"),
           "75 .. 95: a camera program's export", origin=False),
    Source("H.264 video, crf (0 = lossless)", "1",
           _key("render.video.quality", when=lambda row: row.get("render.video.codec") == "h264"),
           "18 .. 28: a video export for sharing", origin=False),
    Source("defocus, focus on the trough's front face: aperture f / N", "mm", _aperture(False),
           "f/2.8 .. f/16 of a 50 mm lens (17.9 .. 3.1 mm): a lab focuses on what it sees "
           "sharpest, the contour 15 mm before the ball"),
    Source("defocus, focus on the ball's plane: aperture f / N", "mm", _aperture(True),
           "f/2.8 .. f/16 of a 50 mm lens (17.9 .. 3.1 mm)"),
    Source("air drag, Cd (room air 1.2 kg/m^3)", "1",
           _key("scenario.environment.air_cd",
                when=lambda row: (_num(row.get("scenario.environment.air_density_kg_m3"))
                                  or 0.0) > 0),
           "always there: Cd 0.47 (smooth sphere) .. 1-4 at Re 30 .. 170 near a wall"),
    Source("rolling resistance rising with speed, mu_speed", "s/m",
           _key("scenario.motion.mu_speed_s_m"),
           "unknown for steel on aluminium; rollfric's --model velocity fits it"),
)


def classify(row: dict, swept: list[str]) -> tuple[str, float | None, str, object]:
    """(source name, magnitude, unit, corrected) of one case.

    Parameters
    ----------
    row : dict
        The case's row of the sweep table (parameters and metrics).
    swept : list of str
        The sweep's swept keys (for sources not in :data:`SOURCES`).

    Returns
    -------
    tuple
        The source's name ("none" for a case without an error), its magnitude (None for
        "none"), its unit and whether rollfric's correction was on (None: it has none).
    """
    for s in SOURCES:
        m = s.magnitude(row)
        if m is not None:
            return s.name, m, s.unit, (None if s.corrected is None else bool(s.corrected(row)))
    keys = [k for k in swept if k not in CORRECTION_KEYS and row.get(k) is not None
            and not (isinstance(row.get(k), float) and math.isnan(row.get(k)))]
    if not keys:
        return "none", None, "", None
    mag = None
    for k in keys:
        v = row.get(k)
        lst = _list(v)
        mag = _num(lst[0]) if lst else _num(v)
        if mag is not None:
            break
    corrected = None
    if "measure.offset" in swept and row.get("measure.offset") is not None:
        corrected = _offset_on(row)
    return ", ".join(keys), mag, "", corrected


STUDY_METRICS = ("mu_bias_rel", "fit_relative_error", "theta_rms_rad", "mu_stderr", "mu_true",
                 "trough_center_err_x_px", "trough_center_err_y_px", "offset_fitted")


def study_rows(df, swept: list[str]) -> list[dict]:
    """The study's rows from a sweep table (one a finished case).

    Parameters
    ----------
    df : pandas.DataFrame
        results.parquet of the sweep.
    swept : list of str
        Its swept keys.

    Returns
    -------
    list of dict
        source, magnitude, unit, corrected, stages and :data:`STUDY_METRICS`.
    """
    out = []
    for _, r in df.iterrows():
        if r.get("status") != "ok":
            continue
        row = {k: (None if isinstance(v, float) and math.isnan(v) else v)
               for k, v in r.to_dict().items()}
        name, mag, unit, corr = classify(row, swept)
        item = {"case_id": row["case_id"], "source": name, "magnitude": mag, "unit": unit,
                "corrected": corr, "stages": row.get("stages") or "full"}
        for m in STUDY_METRICS:
            v = row.get(m)
            item[m] = bool(v) if isinstance(v, bool) else _num(v)
        out.append(item)
    return out


def crossing(points: list[tuple[float, float]], level: float, origin: bool):
    """Where |bias| first reaches ``level`` along the swept magnitudes.

    Parameters
    ----------
    points : list of (magnitude, bias)
        One source's cases (one sign of the magnitude, or both: |magnitude| is used).
    level : float
        |bias| to reach.
    origin : bool
        Start from (0, 0) (magnitude 0 is no error).

    Returns
    -------
    tuple
        (kind, value): ("at", m) interpolated linearly; ("above", m_max): not reached up to the
        largest |magnitude| swept; ("below", m_min): already beyond at the smallest one (no
        origin). A source whose bias falls as its magnitude grows (a working distance):
        ("decreasing", m): beyond the level below m; ("nowhere", m_min): not reached down to
        the smallest magnitude; ("everywhere", m_max): beyond it even at the largest.
    """
    pts = sorted((abs(m), abs(b)) for m, b in points if m is not None and b is not None)
    if not pts:
        return ("none", None)
    if origin:
        pts = [(0.0, 0.0), *pts]
    increasing = pts[-1][1] >= pts[0][1]
    seq = pts if increasing else pts[::-1]
    if seq[0][1] >= level:
        return ("below" if increasing else "everywhere", seq[0][0])
    for (m0, b0), (m1, b1) in zip(seq, seq[1:], strict=False):
        if b0 < level <= b1:
            m = m0 + (level - b0) * (m1 - m0) / (b1 - b0)
            return ("at" if increasing else "decreasing", m)
    return ("above" if increasing else "nowhere", seq[-1][0])


def budget_table(rows: list[dict]) -> list[dict]:
    """The error-budget table: one entry per source and correction state.

    Parameters
    ----------
    rows : list of dict
        :func:`study_rows`'s rows (or the study JSON's ``rows``).

    Returns
    -------
    list of dict
        source, unit, corrected, typical, n, range (min, max |magnitude|), the crossings of
        :data:`LEVELS` (:func:`crossing`), the largest |mu bias| and relative error, the stages.
    """
    by = {s.name: s for s in SOURCES}
    groups: dict = {}
    for r in rows:
        if r["source"] == "none" or r["magnitude"] is None:
            continue
        groups.setdefault((r["source"], r["corrected"]), []).append(r)
    order = {s.name: i for i, s in enumerate(SOURCES)}
    out = []
    for (name, corr), rs in sorted(groups.items(),
                                   key=lambda kv: (order.get(kv[0][0], len(order)), kv[0][0],
                                                   str(kv[0][1]))):
        src = by.get(name)
        origin = src.origin if src else True
        pts = [(r["magnitude"], r["mu_bias_rel"]) for r in rs]
        mags = [abs(r["magnitude"]) for r in rs]
        out.append({
            "source": name, "unit": rs[0]["unit"], "corrected": corr,
            "typical": src.typical if src else "",
            "n": len(rs), "range": [min(mags), max(mags)],
            "levels": {f"{lv:g}": crossing(pts, lv, origin) for lv in LEVELS},
            "max_abs_mu_bias_rel": max(abs(r["mu_bias_rel"]) for r in rs
                                       if r["mu_bias_rel"] is not None),
            "max_fit_relative_error": max((r["fit_relative_error"] for r in rs
                                           if r["fit_relative_error"] is not None),
                                          default=None),
            "stages": sorted({r["stages"] for r in rs}),
        })
    return out


def fmt_mag(v: float) -> str:
    """A magnitude to 2 significant figures."""
    if v == 0:
        return "0"
    return f"{v:.2g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.1e}"


def fmt_crossing(c, unit: str) -> str:
    """A table cell for a :func:`crossing`."""
    kind, v = c
    u = f" {unit}" if unit and unit != "1" else ""
    if kind == "at" or kind == "decreasing":
        return ("" if kind == "at" else "below ") + fmt_mag(v) + u
    if kind == "above":
        return f"not reached (> {fmt_mag(v)}{u})"
    if kind == "below":
        return f"< {fmt_mag(v)}{u}"
    if kind == "nowhere":
        return f"not reached (down to {fmt_mag(v)}{u})"
    if kind == "everywhere":
        return f"beyond it up to {fmt_mag(v)}{u}"
    return ""


def render_markdown(data: dict) -> str:
    """The docs' error-budget table (Markdown) from the study JSON.

    Parameters
    ----------
    data : dict
        The study JSON: ``meta`` and ``rows`` (:func:`study_rows`).

    Returns
    -------
    str
    """
    meta = data.get("meta", {})
    rows = data.get("rows", [])
    table = budget_table(rows)
    base = [r for r in rows if r["source"] == "none"]
    lines = [f"**Run:** {meta.get('date', 'unknown date')}, {meta.get('n_cases', len(rows))} "
             f"cases ({meta.get('note', '')}).", ""]
    if base:
        lines += ["Without an error: " + "; ".join(
            f"mu bias {100 * r['mu_bias_rel']:+.4f} %, relative error "
            f"{100 * r['fit_relative_error']:.3f} % ({r['stages']})" for r in base) + ".", ""]
    lines += ["| source | rollfric's correction | mu bias 0.1 % at | mu bias 1 % at | "
              "swept | largest mu bias | largest relative error (eq. 14) | a lab's range |",
              "|---|---|---|---|---|---|---|---|"]
    for t in table:
        corr = {None: "none", True: "on", False: "off"}[t["corrected"]]
        lo, hi = t["range"]
        st = "+".join(t["stages"])
        rel = t["max_fit_relative_error"]
        lines.append(
            f"| {t['source']} | {corr} | {fmt_crossing(t['levels']['0.001'], t['unit'])} | "
            f"{fmt_crossing(t['levels']['0.01'], t['unit'])} | {fmt_mag(lo)} .. {fmt_mag(hi)}"
            f"{' ' + t['unit'] if t['unit'] and t['unit'] != '1' else ''} ({t['n']}, {st}) | "
            f"{100 * t['max_abs_mu_bias_rel']:.3g} % | "
            f"{'' if rel is None else f'{100 * rel:.3g} %'} | {t['typical']} |")
    for f in meta.get("failed", []):
        what = ", ".join(f"{k} = {v}" for k, v in f["params"].items())
        lines += ["", f"Refused by rollfric ({f['stages']}): {what}: {f['error']}"]
    if meta.get("not_run"):
        lines += ["", f"Not run: {meta['not_run']} case(s) of the sweep file."]
    return "\n".join(lines) + "\n"


def study_json(out: str | Path, note: str = "") -> dict:
    """The study JSON of a finished ``systematics`` sweep folder.

    Parameters
    ----------
    out : str or pathlib.Path
        The sweep's --out folder (results.parquet, sweep.toml).
    note : str
        How it was run (machine, load), for the page.

    Returns
    -------
    dict
        ``meta`` (date, n_cases, note, swept) and ``rows``.
    """
    import pandas as pd

    out = Path(out)
    df = pd.read_parquet(out / "results.parquet")
    spec = load_sweep(out / "sweep.toml")
    rows = study_rows(df, list(spec.swept))
    failed = []
    for c in spec.cases:
        r = df[df["case_id"] == c.case_id]
        if len(r) and r["status"].iloc[0] != "ok":
            failed.append({"params": {k: v for k, v in c.params.items()
                                      if k != "render.camera.lens_matrix"},
                           "stages": c.stages, "error": str(r["error"].iloc[0])})
    return {"meta": {"date": time.strftime("%Y-%m-%d", time.gmtime()), "n_cases": len(rows),
                     "note": note, "swept": list(spec.swept), "failed": failed,
                     "not_run": len(spec.cases) - len(df)},
            "rows": rows}


def main(argv=None) -> int:
    """``python -m validation.studies.systematics OUT --json PATH [--note TEXT]``."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m validation.studies.systematics",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="the systematics sweep's --out folder")
    ap.add_argument("--json", required=True, help="where to write the study JSON")
    ap.add_argument("--note", default="", help="how it was run (machine, load)")
    args = ap.parse_args(argv)
    if not (Path(args.out) / "results.parquet").is_file():
        print(f"error: {args.out}: no results.parquet (run rollfric sweep systematics "
              f"--out {args.out} first)")
        return 2
    data = study_json(args.out, args.note)
    write_text(Path(args.json), json.dumps(data, indent=1) + "\n")
    print(render_markdown(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
