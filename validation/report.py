"""The report directory of one end-to-end case, and its short text summary.

Files (all written to a temporary name and renamed)::

    metrics.json        the flat metric dict (NaN -> null), plus the case's timings
    case.toml           the case that was run (loads back with ``rollfric validate case.toml``)
    fit.json            rollfric's fit of the measured track; fit_truth.json: the same fitter on
                        the engine's ground-truth theta(t)
    frames.csv          per frame: truth (silhouette centre, theta), located centre, errors
    angle_vs_model.png  measured theta(t) against the fitted equation of motion, with residuals
    center_error_hist.png   histogram of the per-frame centre error (x, y, |e|)
    center_error_vs_time.png    centre error (x, y) and theta error against time
    overlays.png        frames with the located circle/centre and the true centre (zoomed)
    full_frame.png      the whole frame: the trough's axis, the centre's circle, the located path
    report.html         all of it on one self-contained page (images embedded), verdict first
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from rollfric.io import readers as io
from rollfric.output.atomic import replacing, write_text
from rollfric.output.jsonfile import (
    json_safe,  # noqa: F401  (validation.cli prints with it)
    save_fit,
)
from rollfric.output.overlay import plot_full_frame
from rollfric.output.plots import plot_fit
from validation import html_report
from validation.case import dumps_case

# everything a report folder may hold from validate (rollfric.output.folder: --overwrite replaces or
# removes only these names; recording.zarr with --keep-recording)
OUTPUTS = {name: "file" for name in (
    "metrics.json", "case.toml", "setup.toml", "fit.json", "fit_truth.json", "frames.csv",
    "angle_vs_model.png", "center_error_hist.png", "center_error_vs_time.png", "overlays.png",
    "full_frame.png", "report.html")}
OUTPUTS["recording.zarr"] = "folder"


def _savefig(fig, path: Path) -> None:
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)


def write_report(result, out: str | Path, *, overlay_frames: int = 6) -> Path:
    """Write the report of a :class:`validation.e2e.CaseResult` into ``out`` (created)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    m = result.metrics
    write_text(out / "metrics.json", json.dumps(json_safe(m), indent=2, sort_keys=True) + "\n")
    write_text(out / "case.toml", dumps_case(result.case.data))
    write_text(out / "setup.toml", dumps_setup_dict(result.setup_dict))
    save_fit(result.fit, out / "fit.json")
    save_fit(result.fit_truth, out / "fit_truth.json")
    pf = per_frame_errors(result)
    with replacing(out / "frames.csv") as tmp:
        pf.to_csv(tmp, index=False, float_format="%.9g")

    # angle vs model
    tr = result.track
    plot_fit(tr["t_s"].to_numpy(float), tr["theta_rad"].to_numpy(float), result.fit,
             out / "angle_vs_model.png",
             title=(f"{result.case.name}: mu recovered {m['mu_recovered']:.6f} "
                    f"(true {m['mu_true']:.6f}, bias {_pct(m['mu_bias_rel'])})"))

    good = pf["found"].to_numpy(bool) & np.isfinite(pf["err_px"].to_numpy(float))
    # centre-error histogram
    fig = Figure(figsize=(12, 3.6))  # no pyplot: no backend, no global figure state
    axes = fig.subplots(1, 3)
    for ax, col, label in zip(axes, ("err_x_px", "err_y_px", "err_px"),
                              ("x error (px)", "y error (px)", "|error| (px)"), strict=True):
        v = pf.loc[good, col].to_numpy(float)
        if v.size:
            ax.hist(v, bins=min(60, max(10, v.size // 20)), color="tab:blue", alpha=0.8)
            ax.axvline(0, color="k", lw=0.8)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("frames")
    fig.suptitle(f"centre error vs silhouette truth: rms {m['center_rms_px']:.3f} px, "
                 f"max {m['center_max_px']:.3f} px, {100 * m['found_fraction']:.1f} % located")
    fig.tight_layout()
    _savefig(fig, out / "center_error_hist.png")

    # error vs time
    fig = Figure(figsize=(10, 5.5))
    a1, a2 = fig.subplots(2, 1, sharex=True)
    t = pf["t_s"].to_numpy(float)
    a1.plot(t, pf["err_x_px"], ".", ms=1.5, label="x")
    a1.plot(t, pf["err_y_px"], ".", ms=1.5, label="y")
    miss = ~pf["found"].to_numpy(bool)
    if miss.any():
        a1.plot(t[miss], np.zeros(miss.sum()), "x", color="r", ms=4, label="not found")
    a1.set_ylabel("centre error (px)")
    a1.legend(loc="upper right", markerscale=4)
    a1.grid(alpha=0.3)
    a2.plot(t, np.degrees(pf["err_theta_rad"]), ".", ms=1.5, color="0.3")
    a2.set_ylabel("theta error (deg)")
    a2.set_xlabel("t (s)")
    a2.grid(alpha=0.3)
    fig.tight_layout()
    _savefig(fig, out / "center_error_vs_time.png")

    if result.recording is not None:
        _overlays(result, pf, out / "overlays.png", overlay_frames)
        plot_full_frame(io.open_recording(result.recording), result.track, result.track_info,
                        out / "full_frame.png")
    write_html(result, out)
    return out


def write_html(result, out: Path) -> Path:
    """``out/report.html``: the verdict, the summary and the report's figures on one page."""
    m = result.metrics
    verdict = _verdict_lines(m)
    words = verdict[0].split("verdict", 1)[1].strip() if verdict else (
        f"mu recovered {m['mu_recovered']:.6f} against the true {m['mu_true']:.6f} "
        f"(bias {_pct(m['mu_bias_rel'])}); no uncertainty budget was computed")
    figures = [
        (out / "full_frame.png", "Where did it look? The whole frame with the trough's axis, "
                                 "the circle the ball's centre runs on, and the located path."),
        (out / "angle_vs_model.png", "Does the equation of motion fit the measured angle? "
                                     "theta(t) with the fit, and what is left over."),
        (out / "center_error_vs_time.png", "How far is each located centre from the truth, "
                                           "frame by frame?"),
        (out / "center_error_hist.png", "How are the centre errors distributed?"),
        (out / "overlays.png", "What did the locator see? Frames with the located circle and "
                               "the true centre."),
    ]
    page = html_report.render(f"rollfric validate: {result.case.name}", words,
                              bool(m.get("within_U", True)), summary_text(result), figures)
    write_text(out / "report.html", page)
    return out / "report.html"


def _overlays(result, pf, path: Path, k: int) -> None:
    """Zoomed frames with the located circle (blue), its centre (+) and the true centre (x)."""
    src = io.open_recording(result.recording)
    n = len(pf)
    # the worst-located frame and frames spread over the record
    picks = list(np.unique(np.linspace(0, n - 1, max(1, k - 1)).round().astype(int)))
    err = pf["err_px"].to_numpy(float)
    if np.isfinite(err).any():
        worst = int(np.nanargmax(err))
        if worst not in picks:
            picks.append(worst)
    r = float(result.metrics.get("ball_radius_px", 10.0))
    ncol = min(3, len(picks))
    nrow = math.ceil(len(picks) / ncol)
    fig = Figure(figsize=(4 * ncol, 4 * nrow))
    axes = fig.subplots(nrow, ncol, squeeze=False)
    half = int(math.ceil(1.5 * r)) + 4
    h, w = src.shape[1:]
    # the errors are hundredths of a pixel: drawn as arrows magnified by a power of ten
    worst_err = float(np.nanmax(err)) if np.isfinite(err).any() else 0.0
    gain = 1.0
    if worst_err > 0:  # the largest of 1, 2, 5 x 10^k that draws the worst error <= r / 2
        decade = 10.0 ** math.floor(math.log10(0.5 * r / worst_err))
        gain = max(g * decade for g in (1, 2, 5) if g * decade * worst_err <= 0.5 * r)
    for ax, i in zip(axes.flat, picks, strict=False):
        row = pf.iloc[int(i)]
        cx, cy = float(row["truth_x_px"]), float(row["truth_y_px"])
        x0, y0 = int(round(cx)) - half, int(round(cy)) - half
        x0c, y0c = max(0, x0), max(0, y0)
        y1c, x1c = min(h, y0c + 2 * half + 1), min(w, x0c + 2 * half + 1)
        if y1c > y0c and x1c > x0c:  # the crop's region alone (the same pixels)
            crop = np.asarray(src.read(int(i), (y0c, y1c, x0c, x1c)))
        else:
            crop = np.asarray(src[int(i)])[y0c:y1c, x0c:x1c]
        ext = (x0c - 0.5, x0c + crop.shape[1] - 0.5, y0c + crop.shape[0] - 0.5, y0c - 0.5)
        ax.imshow(crop, cmap="gray", extent=ext, interpolation="nearest")
        if row["found"] and np.isfinite(row["x_px"]):
            ax.add_patch(Circle((row["x_px"], row["y_px"]), r, fill=False, color="tab:blue",
                                lw=1))
            ax.annotate("", xy=(cx + gain * (row["x_px"] - cx), cy + gain * (row["y_px"] - cy)),
                        xytext=(cx, cy), arrowprops={"arrowstyle": "-|>", "color": "tab:blue",
                                                     "lw": 2})
            title = f"frame {i}: error {row['err_px']:.3f} px"
        else:
            title = f"frame {i}: not found"
        ax.plot(cx, cy, "x", color="tab:red", ms=8, mew=1.5)
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(picks):]:
        ax.axis("off")
    fig.suptitle(f"located circle (blue) and the error from the true centre (red x) to the located "
                 f"one, drawn x{gain:g} (axes in px)")
    fig.tight_layout()
    _savefig(fig, path)


def _mode_text(m: dict) -> str:
    if m["mode"] == "oracle":
        return "the exact setup and center_px given"
    where = "measured by the lab" if m.get("lab_center_measured") else "from the contour"
    return (f"the lab's nominal setup, trough centre {where}, off the truth by "
            f"({m['trough_center_err_x_px']:+.3f}, {m['trough_center_err_y_px']:+.3f}) px")


def dumps_setup_dict(d: dict) -> str:
    """A setup file's dict (lab-file form) as TOML text."""
    lines = []
    for section, table in d.items():
        lines.append(f"[{section}]")
        for key, value in table.items():
            lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, int):
        return str(v)
    return json.dumps(str(v))


def _pct(rel: float) -> str:
    """A relative error in percent: two decimals, or two significant digits when smaller, down
    to four decimals (+0.0047 %, not +0.00 %)."""
    if not math.isfinite(rel):
        return "n/a"
    if rel == 0:
        return "0 %"
    digits = min(4, max(2, 1 - math.floor(math.log10(abs(100 * rel)))))
    return f"{100 * rel:+.{digits}f} %"


def _verdict_lines(m: dict) -> list[str]:
    """The answer first, in words: is the truth within the measurement's uncertainty?"""
    if "u_mu" not in m:
        return []
    z = m["z_budget"]
    if m["within_U"]:
        words = (f"mu agrees with the truth within U(mu) (error {abs(z):.2f} u(mu);"
                 " U(mu) = 2 u(mu))")
    else:
        words = (f"mu is OUTSIDE U(mu) of the truth (error {abs(z):.1f} u(mu); U(mu) = 2 u(mu)):"
                 " the measurement or its budget misses something")
    return [f"  verdict        {words}", ""]


def summary_text(result, out: str | Path | None = None) -> str:
    """A short readable summary of one case."""
    m = result.metrics
    c = result.case
    sc = c.scenario
    tm = result.timings
    lines = [
        f"rollfric validate: {c.name} (case {m['case_id']})",
        f"  scenario   {sc.ball_diameter * 1e3:g} mm ball, trough R"
        f" {sc.cylinder_radius * 1e3:g} mm,"
        f" theta0 {math.degrees(sc.theta0):g} deg, {sc.duration:g} s at {sc.fps:g} Hz,"
        f" engine {sc.engine}/{sc.surface}",
        f"  camera     {c.scene.camera.width}x{c.scene.camera.height} px,"
        f" {sc.pixel_size * 1e3:g} mm/px, motion blur {c.scene.motion_blur} sub-frame(s),"
        f" sensor {c.data['render'].get('noise')}, lighting {c.data['render'].get('lighting')},"
        f" seed {c.render_seed}",
        f"  measure    {m['mode']} mode ({_mode_text(m)}), locator {c.locator}, fit {c.fit}"
        f"{' + offset' if m.get('offset_fitted') else ''}",
        "",
        *_verdict_lines(m),
        f"  mu true        {m['mu_true']:.6f}",
        f"  mu recovered   {m['mu_recovered']:.6f}   bias {_pct(m['mu_bias_rel'])}",
        *([f"  uncertainty    u(mu) {m['u_mu']:.2g} ({100 * m['u_mu'] / m['mu_recovered']:.2g} %),"
           f" U(mu) {m['U_mu']:.2g} (k = 2), largest source: {m['budget_top_source']}"]
          if "u_mu" in m else []),
        f"  fit alone      stderr {m['mu_stderr']:.2g} (the statistical part only;"
        f" x {m['mu_stderr_ar1'] / m['mu_stderr']:.2f} for the residuals' lag-1"
        f" autocorrelation {m['residual_lag1_autocorr']:.2f})",
        f"  mu engine      {m['mu_engine']:.6f}"
        f"   (engine bias {_pct(m['mu_engine_bias_rel'])},"
        f" pipeline bias {_pct(m['mu_pipeline_bias_rel'])})",
        f"  centre error   rms {m['center_rms_px']:.4f} px, max {m['center_max_px']:.4f} px,"
        f" bias ({m['center_bias_x_px']:+.4f}, {m['center_bias_y_px']:+.4f}) px",
        f"  theta error    rms {math.degrees(m['theta_rms_rad']):.5f} deg,"
        f" max {math.degrees(m['theta_max_rad']):.5f} deg",
        f"  located        {m['n_found']} of {m['n_frames']} frames"
        f" ({100 * m['found_fraction']:.1f} %)",
        "  time           " + ", ".join(
            f"{k} {v:.1f} s" + (" (beside render)" if k == "fit_truth"
                                and m.get("fit_truth_beside_render") else "")
            for k, v in tm.items()),
    ]
    if out is not None:
        lines += ["", f"  report: {Path(out).resolve() / 'report.html'} (open it in a browser;"
                      " beside it metrics.json, fit.json, frames.csv and the figures)"]
    return "\n".join(lines)


def per_frame_errors(result):
    """DataFrame per frame of a :class:`validation.e2e.CaseResult`: truth, located centre,
    errors (px, rad), found flag."""
    import pandas as pd

    tt = result.truth
    tr = result.track.set_index("frame") if "frame" in result.track.columns else result.track
    tr = tr.reindex(range(len(tt)))
    out = pd.DataFrame({
        "frame": np.arange(len(tt)),
        "t_s": np.asarray(tt["t_s"], float),
        "truth_x_px": np.asarray(tt["sil_x_px"], float),
        "truth_y_px": np.asarray(tt["sil_y_px"], float),
        "truth_theta_rad": np.asarray(tt["theta_rad"], float),
        "x_px": np.asarray(tr["x_px"], float),
        "y_px": np.asarray(tr["y_px"], float),
        "theta_rad": np.asarray(tr["theta_rad"], float),
        "found": np.asarray(tr["found"].fillna(False), dtype=bool) if "found" in tr.columns
        else np.isfinite(np.asarray(tr["x_px"], float)),
    })
    out["err_x_px"] = out["x_px"] - out["truth_x_px"]
    out["err_y_px"] = out["y_px"] - out["truth_y_px"]
    out["err_px"] = np.hypot(out["err_x_px"], out["err_y_px"])
    out["err_theta_rad"] = out["theta_rad"] - out["truth_theta_rad"]
    return out
