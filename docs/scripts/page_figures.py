"""Make the figures that open the pages guide_figures.py does not cover (docs/img/pages/):
combine, safety, how it works and its architecture, and the track.csv and setup.toml formats.

Drawn from the code itself where the page describes it: the combine figure is
``rollfric.uncertainty.combine.combine`` on four drawn releases, the architecture's arrows are the
import
statements of the four packages, the format figures are the shipped sample measured as
``rollfric measure`` does. Seconds once the locator's kernels are compiled.

Usage (from the repository root)::

    PYTHONPATH=$PWD python docs/scripts/page_figures.py
"""

from __future__ import annotations

import ast
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, FancyArrowPatch, FancyBboxPatch, Rectangle  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "img" / "pages"
DPI = 110
PACKAGES = ("rollfric", "sim", "synth", "validation")


# -- drawing helpers ---------------------------------------------------------------------------

def _box(ax, x, y, w, h, text, fc="#e8f0fa", ec="#34659c", fs=8.5, **kw):
    """A rounded box centred on (x, y) with its text; returns its patch."""
    p = FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.02,rounding_size=0.04",
                       fc=fc, ec=ec, lw=1.1, **kw)
    ax.add_patch(p)
    ax.text(x, y, text, ha="center", va="center", fontsize=fs, wrap=True)
    return p


def _arrow(ax, a, b, color="0.25", ls="-", text=None, fs=7.5, rad=0.0, shrink=0):
    """An arrow from patch (or point) a to patch (or point) b, with an optional label."""
    kw = {"posA": a, "posB": b} if isinstance(a, tuple) else {"patchA": a, "patchB": b,
                                                                "posA": _centre(a),
                                                                "posB": _centre(b)}
    arr = FancyArrowPatch(arrowstyle="-|>", mutation_scale=11, color=color, lw=1.1, ls=ls,
                          connectionstyle=f"arc3,rad={rad}", shrinkA=shrink, shrinkB=shrink,
                          **kw)
    ax.add_patch(arr)
    if text:
        pa, pb = kw["posA"], kw["posB"]
        ax.text((pa[0] + pb[0]) / 2, (pa[1] + pb[1]) / 2, text, ha="center", va="center",
                fontsize=fs, color=color, bbox={"fc": "white", "ec": "none", "pad": 0.5})
    return arr


def _centre(p):
    b = p.get_bbox()
    return ((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2)


def _canvas(w, h, figsize):
    fig, ax = plt.subplots(figsize=figsize)
    fig.subplots_adjust(0.01, 0.01, 0.99, 0.93)
    ax.set_xlim(0, w)
    ax.set_ylim(0, h)
    ax.set_axis_off()
    return fig, ax


# -- combine ------------------------------------------------------------------------------------

def combine_example(out, seed=3):
    """Four drawn releases of one setup combined by rollfric.uncertainty.combine.combine: each
    release's
    independent u, the combined mu, its u with and without the shared (setup) part, and where
    the Birge ratio falls in its expected range."""
    from scipy import stats

    from rollfric.uncertainty.combine import Run, birge_range, combine

    rng = np.random.default_rng(seed)
    truth, u_ind, u_radius = 0.0079, np.array([3e-5, 2e-5, 4e-5, 2.5e-5]), 2.2e-5
    shared_error = u_radius * rng.standard_normal()  # one trough radius: common to all
    mus = truth + shared_error + u_ind * rng.standard_normal(len(u_ind))
    runs = [Run(path=f"release {i + 1}", mu=float(m), u_independent=float(u),
                u_mu=float(np.hypot(u, u_radius)),
                shared={"trough radius": (u_radius, 85.3)}, quality="ok", quality_codes=(),
                setup=None) for i, (m, u) in enumerate(zip(mus, u_ind, strict=True))]
    c = combine(runs)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9.5, 3.6), constrained_layout=True,
                                 gridspec_kw={"width_ratios": [1.5, 1]})
    x = np.arange(1, len(runs) + 1)
    k = 1e3
    a1.axhspan((c.mu - c.U_mu) * k, (c.mu + c.U_mu) * k, color="C0", alpha=0.10,
               label=f"combined U = 2u = {c.U_mu:.2g}")
    a1.axhspan((c.mu - c.mu_u) * k, (c.mu + c.mu_u) * k, color="C0", alpha=0.22,
               label=f"combined u = {c.mu_u:.2g} (independent and shared)")
    a1.axhspan((c.mu - c.u_independent) * k, (c.mu + c.u_independent) * k, color="C0",
               alpha=0.45, label=f"its independent part {c.u_independent:.2g}")
    a1.axhline(c.mu * k, color="C0", lw=1.2)
    a1.errorbar(x, mus * k, yerr=u_ind * k, fmt="o", color="k", capsize=3,
                label="each release, its independent u")
    a1.axhline(truth * k, color="C3", ls="--", lw=0.9, label=f"truth {truth}")
    a1.set_xticks(x, [r.path for r in runs])
    a1.set_ylabel("mu x 1000")
    a1.set_xlim(0.4, len(runs) + 1.9)
    a1.legend(fontsize=7, loc="upper right")
    a1.set_title("four releases on one trough (radius u_mu 2.2e-5, shared): the mean's u does "
                 "not\nshrink below the shared part however many releases", fontsize=9)
    n = len(runs)
    lo, hi = birge_range(n)
    r = np.linspace(0.001, 2.6, 400)
    pdf = stats.chi2.pdf((n - 1) * r ** 2, n - 1) * 2 * (n - 1) * r
    a2.plot(r, pdf, color="0.3", lw=1.0, label=f"R_B of consistent runs, N = {n}")
    a2.fill_between(r, pdf, where=(r >= lo) & (r <= hi), color="C2", alpha=0.25,
                    label=f"its 95 % range [{lo:.2f}, {hi:.2f}]")
    a2.fill_between(r, pdf, where=r > hi, color="C3", alpha=0.35,
                    label="above: suspect, exit status 3")
    a2.axvline(c.birge_ratio, color="C0", lw=1.5, label=f"these releases: {c.birge_ratio:.2f}")
    a2.set_xlabel("Birge ratio R_B")
    a2.set_ylabel("probability density")
    a2.set_yticks([])
    a2.legend(fontsize=7)
    a2.set_title("do they scatter as their budgets say?", fontsize=9)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)
    return c


# -- safety -------------------------------------------------------------------------------------

def safety(out):
    """What a run does with --out DIR: checks, a claim, a hidden folder, one rename."""
    fig, ax = _canvas(10, 4.6, (10, 4.6))
    steps = [
        (1.1, "1. check every\ndestination\n(exists? --overwrite?\nan input?)"),
        (3.2, "2. claim DIR:\nlock .DIR.claim-rollfric\n(held until the\nrun ends or dies)"),
        (5.4, "3. write every output\ninto .DIR.part-PID-START\nbeside DIR\n(hidden, new)"),
        (7.6, "4. one step: rename it\nto DIR, or swap it with\nthe old DIR (renameat2),"
              "\nyour files linked across"),
    ]
    boxes = [_box(ax, x, 3.3, 1.9, 1.25, t, fs=8) for x, t in steps]
    done = _box(ax, 9.45, 3.3, 0.95, 1.25, "DIR:\nthe new\noutputs", fc="#e3f4e3", ec="#2e7d32",
                fs=8)
    chain = [*boxes, done]
    for a, b in zip(chain, chain[1:], strict=False):
        _arrow(ax, a, b)
    fails = [
        (1.1, "exit 2, one line naming it:\nnothing read, nothing written"),
        (3.2, "another run writes DIR:\nexit 2, nothing written"),
        (5.4, "error, Ctrl-C, kill: DIR as it was;\nthe next run removes the .part"),
        (7.6, "killed at any moment:\nthe old DIR or the new,\nnever a mix"),
    ]
    for (x, t), b in zip(fails, boxes, strict=True):
        f = _box(ax, x, 1.0, 1.95, 0.95, t, fc="#fdeaea", ec="#b23b3b", fs=7.5)
        _arrow(ax, b, f, color="#b23b3b")
    ax.set_title("what a run does with --out DIR (measure, validate, bench, render --export): "
                 "your folder holds the old outputs or the new, never half of them", fontsize=9.5)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


# -- architecture -------------------------------------------------------------------------------

def import_edges(root=ROOT) -> set[tuple[str, str]]:
    """(importer, imported) between the four packages, from every import statement in their
    modules (also those inside functions)."""
    edges = set()
    for pkg in PACKAGES:
        for p in (root / pkg).rglob("*.py"):
            for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                for n in names:
                    top = n.split(".")[0]
                    if top in PACKAGES and top != pkg:
                        edges.add((pkg, top))
    return edges


def architecture(out):
    """The data flow (top) and which package imports which (bottom), the arrows of the
    bottom row read from the code."""
    fig, ax = _canvas(12, 5.6, (11, 5.1))
    data = {"scenario": (0.8, "scenario\n(TOML)"), "trajectory": (4.0, "trajectory\n(CSV)"),
            "recording": (7.2, "recording\n+ setup.toml"), "result": (10.5, "track.csv,\nfit.json")}
    pkgs = {"sim": (2.4, "sim\nengines"), "synth": (5.6, "synth\nrenderer"),
            "rollfric": (8.85, "rollfric\nthe measurement")}
    y = 4.5
    pd_ = {k: _box(ax, x, y, 1.3, 0.8, t, fc="white", ec="0.45", fs=8)
           for k, (x, t) in data.items()}
    pp = {k: _box(ax, x, y, 1.35, 0.8, t, fs=8.5) for k, (x, t) in pkgs.items()}
    chain = [pd_["scenario"], pp["sim"], pd_["trajectory"], pp["synth"], pd_["recording"],
             pp["rollfric"], pd_["result"]]
    for a, b in zip(chain, chain[1:], strict=False):
        _arrow(ax, a, b)
    vb = _box(ax, 5.6, 3.05, 9.0, 0.55,
              "validation: runs the chain on a case and compares the result with the "
              "truth (rollfric validate, sweep, bench)", fc="#fff4e0", ec="#b8860b", fs=8)
    for k in pkgs:
        _arrow(ax, (pkgs[k][0], vb.get_bbox().y1), (pkgs[k][0], y - 0.42), color="#b8860b",
               ls="--")
    ax.text(0.1, 5.35, "data flow", fontsize=9, weight="bold")
    # the import graph, as the code has it
    ax.text(0.1, 2.35, "imports (read from the code: an arrow = 'imports from')", fontsize=9,
            weight="bold")
    pos = {"validation": (1.6, 1.0), "synth": (4.6, 1.0), "sim": (7.6, 1.0),
           "rollfric": (10.6, 1.0)}
    ib = {k: _box(ax, x, y_, 1.5, 0.6, k, fs=9,
                  fc="#fff4e0" if k == "validation" else "#e8f0fa",
                  ec="#b8860b" if k == "validation" else "#34659c")
          for k, (x, y_) in pos.items()}
    order = list(pos)
    for a, b in sorted(import_edges()):
        gap = order.index(b) - order.index(a)
        rad = 0.0 if abs(gap) == 1 else (-0.3 if abs(gap) == 2 else 0.15)
        _arrow(ax, ib[a], ib[b], color="0.35", rad=rad)
    ax.text(10.6, 0.35, "imports nothing of the others\n(tests/test_architecture.py)",
            ha="center", va="center", fontsize=7.5, color="#34659c")
    ax.set_title("rollfric's four packages: what flows between them, and which imports which",
                 fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


# rollfric's own packages in the order the data passes through them
INSIDE = ("cli", "measurement", "io", "geometry", "locate", "track", "fit", "uncertainty",
          "output", "setup", "core")


def _rollfric_part(path, root=ROOT) -> str:
    """The part of rollfric a module belongs to: its subpackage, else "core" (errors, registry,
    jit, parallel, sample, the package itself), "measurement" for the recipe module."""
    parts = path.relative_to(root / "rollfric").with_suffix("").parts
    if len(parts) > 1:
        return parts[0]
    return "measurement" if parts[0] == "measurement" else "core"


def rollfric_modules(root=ROOT) -> dict[str, list[str]]:
    """part -> its modules' names (no __init__), sorted."""
    out: dict[str, list[str]] = {}
    for p in sorted((root / "rollfric").rglob("*.py")):
        if p.stem != "__init__":
            inner = p.relative_to(root / "rollfric").with_suffix("").parts[1:]
            name = "/".join(inner) if len(inner) > 1 else p.stem
            out.setdefault(_rollfric_part(p, root), []).append(name)
    return out


def rollfric_edges(root=ROOT) -> dict[tuple[str, str], int]:
    """(importing part, imported part) -> number of import statements, inside rollfric."""
    index = {}
    for p in (root / "rollfric").rglob("*.py"):
        parts = list(p.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        index[".".join(parts)] = _rollfric_part(p, root)
    edges: dict[tuple[str, str], int] = {}
    for p in (root / "rollfric").rglob("*.py"):
        me = _rollfric_part(p, root)
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.startswith("rollfric"):
                targets = [f"{node.module}.{a.name}" for a in node.names] + [node.module]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names if a.name.startswith("rollfric")]
            else:
                continue
            for t in targets:
                while t and t not in index:
                    t = t.rpartition(".")[0]
                if t and t != "rollfric" and index[t] != me:
                    edges[(me, index[t])] = edges.get((me, index[t]), 0) + 1
                    break
    return edges


def rollfric_inside(out):
    """rollfric's packages in the data's order with their modules (left), and which imports
    which, counted from the code (right: a row imports from a column)."""
    mods = rollfric_modules()
    parts = [p for p in INSIDE if p in mods]
    edges = rollfric_edges()
    fig = plt.figure(figsize=(12, 5.6))
    ax = fig.add_axes([0.01, 0.02, 0.55, 0.9])
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    ax.axis("off")
    flow = [p for p in INSIDE[2:-2] if p in mods]
    boxes = {}
    for i, part in enumerate(flow):
        x = 0.75 + i * 1.4
        text = part + "/\n" + "\n".join(mods[part])
        boxes[part] = _box(ax, x, 5.2, 1.3, 5.6, text, fs=6.0)
    for a, b in zip(flow, flow[1:], strict=False):
        _arrow(ax, boxes[a], boxes[b])
    top = "  ".join(f"{p}: {', '.join(mods[p])}" for p in ("cli", "measurement") if p in mods)
    _box(ax, 5.0, 9.1, 9.6, 0.75, top, fc="#fff4e0", ec="#b8860b", fs=6.8)
    bottom = "  ".join(f"{p}: {', '.join(mods[p])}" for p in ("setup", "core") if p in mods)
    _box(ax, 5.0, 1.15, 9.6, 0.75, bottom, fc="white", ec="0.45", fs=6.8)
    ax.text(0.1, 9.75, "the commands and the recipe (rollfric.measure) call the steps",
            fontsize=8)
    ax.text(0.1, 0.3, "used by every step: the setup, errors, the registries, the threads",
            fontsize=8)
    bx = fig.add_axes([0.64, 0.19, 0.34, 0.67])
    m = np.zeros((len(parts), len(parts)))
    for (a, b), n in edges.items():
        if a in parts and b in parts:
            m[parts.index(a), parts.index(b)] = n
    bx.imshow(np.where(m > 0, np.log1p(m), np.nan), cmap="Blues", vmin=0,
              vmax=np.log1p(m.max() or 1))
    for (i, j), n in np.ndenumerate(m):
        if n:
            bx.text(j, i, int(n), ha="center", va="center", fontsize=6.5)
    bx.set_xticks(range(len(parts)), parts, rotation=60, ha="right", fontsize=7.5)
    bx.set_yticks(range(len(parts)), parts, fontsize=7.5)
    bx.set_xlabel("imported", fontsize=8)
    bx.set_ylabel("importing", fontsize=8)
    bx.set_title("import statements between rollfric's parts\n(read from the code)",
                 fontsize=9)
    fig.suptitle("rollfric inside: the data's way through its packages", fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


# -- formats ------------------------------------------------------------------------------------

def _sample_track():
    """The sample measured as ``rollfric measure`` does (no fit)."""
    from rollfric.io.readers import open_recording
    from rollfric.measurement import measure
    from rollfric.sample import sample_path
    from rollfric.setup.model import load_setup

    src = open_recording(sample_path("frames.tif"))
    setup = load_setup(sample_path("setup.toml"))
    df, _, _ = measure(src, setup, None, fit=False)
    return df, setup, src


def track_columns(df, out):
    """track.csv's columns for the shipped sample, against t_s."""
    fig, axes = plt.subplots(3, 1, figsize=(8.5, 5.6), sharex=True, constrained_layout=True,
                             gridspec_kw={"height_ratios": [1, 1, 0.5]})
    t = df["t_s"]
    axes[0].plot(t, df["x_px"], ".", ms=2, label="x_px")
    axes[0].set_ylabel("x_px")
    a0 = axes[0].twinx()
    a0.plot(t, df["y_px"], ".", ms=2, color="C1")
    a0.set_ylabel("y_px", color="C1")
    a0.invert_yaxis()
    axes[0].set_title("x_px (left axis) and y_px (right axis, down): the located centre, "
                      "pixels of the frame", fontsize=9)
    axes[1].plot(t, np.degrees(df["theta_rad"]), ".", ms=2, color="C2")
    axes[1].axhline(0, color="0.7", lw=0.6)
    axes[1].set_ylabel("theta (deg)")
    axes[1].set_title("theta_rad (here in degrees): the angle about the cylinder's axis, > 0 "
                      "right of the bottom; what rollfric fit uses", fontsize=9)
    found = df["found"].to_numpy()
    axes[2].step(t, found, where="mid", color="C0")
    axes[2].set_ylim(-0.2, 1.3)
    axes[2].set_yticks([0, 1])
    axes[2].set_ylabel("found")
    axes[2].set_xlabel("t_s (s)")
    flagged = int((found == 0).sum())
    still = int((df["still"].fillna("").astype(str) != "").sum()) if "still" in df else 0
    axes[2].set_title(f"found: 1 where the ball was located ({len(df) - flagged} of {len(df)} "
                      f"frames; flag names why not; still: {still} frames held or at rest)",
                      fontsize=9)
    fig.suptitle("track.csv of the shipped sample (rollfric sample; rollfric measure): one row "
                 "a frame", fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


def setup_quantities(df, setup, src, out):
    """setup.toml's quantities drawn to scale on the sample: the trough's radius R about its
    axis (center_px), the ball's radius r, the circle its centre moves on (R - r), the pixel
    size as a scale bar, and theta's sign."""
    frame = np.asarray(src[0]).astype(float)
    h, w = frame.shape
    cx, cy = setup.center_px
    px = setup.pixel_size  # m per px
    rr, rb = setup.cylinder_radius / px, setup.ball_diameter / 2 / px
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8.5, 8.2), constrained_layout=True,
                                 gridspec_kw={"height_ratios": [1.55, 1]})
    # top: the whole geometry to scale, the frame where it lies
    a1.add_patch(Circle((cx, cy), rr, fill=False, color="0.3", lw=1.2))
    a1.add_patch(Circle((cx, cy), rr - rb, fill=False, color="C0", ls="--", lw=0.9))
    a1.add_patch(Rectangle((-0.5, -0.5), w, h, fill=False, color="C3", lw=1.4))
    a1.text(w + 15, h / 2, "the frame\n(below)", color="C3", va="center", fontsize=8)
    a1.plot(cx, cy, "k+", ms=10)
    a1.text(cx - 20, cy - 15, "center_px: the axis", fontsize=8, ha="right", va="bottom")
    ang = np.radians(220)
    tip = (cx + rr * np.cos(ang), cy - rr * np.sin(ang))
    a1.annotate("", tip, (cx, cy), arrowprops={"arrowstyle": "-|>", "color": "0.3"})
    a1.text((cx + tip[0]) / 2 - 20, (cy + tip[1]) / 2,
            f"R = radius_mm\n= {setup.cylinder_radius * 1e3:g} mm = {rr:.0f} px", fontsize=8,
            ha="right", va="center")
    th0 = float(df["theta_rad"].iloc[0])
    for th, c in ((0.0, "0.6"), (th0, "C2")):
        a1.plot([cx, cx + (rr - rb) * np.sin(th)], [cy, cy + (rr - rb) * np.cos(th)], color=c,
                lw=1.0)
    arc = np.linspace(0, th0, 30)
    a1.plot(cx + 0.35 * rr * np.sin(arc), cy + 0.35 * rr * np.cos(arc), color="C2", lw=1.0)
    a1.text(cx + 0.35 * rr * np.sin(th0 / 2) + 12, cy + 0.35 * rr * np.cos(th0 / 2),
            f"theta = {np.degrees(th0):+.0f} deg at frame 0 (> 0: right of the bottom)",
            color="C2", fontsize=8, va="center")
    a1.text(cx + (rr - rb) * 0.75, cy + (rr - rb) * 0.3, "the ball's centre: R - r",
            color="C0", fontsize=8)
    a1.set_xlim(cx - rr * 1.08, cx + rr * 1.08)
    a1.set_ylim(h + 60, cy - 110)
    a1.set_aspect("equal")
    a1.set_xlabel("x (px)")
    a1.set_ylabel("y (px, down)")
    a1.set_title("the trough about its axis, to scale: the sample's frame is a strip at its "
                 "bottom", fontsize=9)
    # bottom: the frame itself
    a2.imshow(frame, cmap="gray", vmin=0, vmax=255)
    t = np.linspace(0, 2 * np.pi, 4000)
    for rad, c, ls, lab in ((rr, "y", "-", "trough: R about center_px"),
                            (rr - rb, "C0", "--", "the ball's centre moves on R - r")):
        a2.plot(cx + rad * np.cos(t), cy + rad * np.sin(t), color=c, ls=ls, lw=1.0, label=lab)
    x0, y0 = float(df["x_px"].iloc[0]), float(df["y_px"].iloc[0])
    a2.add_patch(Circle((x0, y0), rb, fill=False, color="C2", lw=1.0))
    a2.annotate("", (x0 + rb, y0), (x0, y0), arrowprops={"arrowstyle": "-|>", "color": "C2"})
    a2.text(x0 - rb - 6, y0 - 22, f"ball: r = diameter_mm / 2 = {rb:.1f} px", color="C2",
            fontsize=8, ha="right", va="center")
    bar = 5e-3 / px
    a2.plot([8, 8 + bar], [h - 6, h - 6], color="w", lw=3)
    a2.text(8, h - 12, f"5 mm = {bar:.1f} px (pixel_size_mm = {px * 1e3:g})", color="w",
            fontsize=8)
    xs = np.array([235.0, 290.0])
    ys = cy + np.sqrt((rr - rb) ** 2 - (xs - cx) ** 2) - 10
    a2.annotate("theta > 0 this way", (xs[1], ys[1]), (xs[0], ys[0]), color="C0", fontsize=8,
                ha="right", va="center",
                arrowprops={"arrowstyle": "-|>", "color": "C0"})
    a2.set_xlim(-0.5, w - 0.5)
    a2.set_ylim(h - 0.5, -0.5)
    a2.legend(fontsize=7, loc="upper left")
    a2.set_xlabel("x (px)")
    a2.set_ylabel("y (px)")
    a2.set_title(f"frame 0 of the sample ({w} x {h} px; center_px = [{cx:g}, {cy:g}], above "
                 "the frame)", fontsize=9)
    fig.suptitle("setup.toml's quantities on the shipped sample", fontsize=10)
    fig.savefig(out, dpi=DPI)
    plt.close(fig)


# -- the physics in the fit ------------------------------------------------------------------

PHYSICS_BALLS = (("1.58mm", 0.0117), ("10mm", 0.0079), ("12.69mm", 0.0065))
PHYSICS_ANGLES = (10, 20, 35)


def physics_terms(setup, mu, theta, theta_dot):
    """The terms of theta'' (rad/s^2) in rollfric's equation of motion with room air
    (:mod:`rollfric.fit.air`): gravity, the rolling resistance's two parts, the drag, and
    what buoyancy and added mass change in the gravity term."""
    from rollfric.fit.air import ADDED_MASS_COEFFICIENT, air_of

    air = air_of(setup)
    beta, _, kd, *_ = air.coefficients(setup.ball_diameter / 2, setup.ball_mass)
    L, g = setup.track_radius, setup.gravity
    den = (1.4 + ADDED_MASS_COEFFICIENT * beta) * L
    v = L * np.abs(theta_dot)
    re = np.maximum(air.reynolds(v, setup.ball_diameter), 1e-9)
    return {
        "gravity, g sin(theta)": (1 - beta) * g * np.abs(np.sin(theta)) / den,
        "rolling resistance, mu g cos(theta)": mu * (1 - beta) * g * np.cos(theta) / den,
        "rolling resistance, mu L theta'^2": mu * (1 + ADDED_MASS_COEFFICIENT * beta) * L
        * theta_dot**2 / den,
        "air drag": kd * air.drag_coefficient(re) * v**2 / den,
        "buoyancy and added mass": np.abs(g * np.sin(theta) * (1 / (1.4 * L)
                                                               - (1 - beta) / den)),
    }


def physics(out, seconds=4.0):
    """The physics in the fit: (a) the size of each term of the equation of motion over a
    swing of the 10 mm ball, (b) what leaving the air out does to mu, against the u(mu)
    that the drag law's own uncertainty leaves when it is in; fitted, not estimated."""
    import rollfric
    from rollfric.fit import eom
    from rollfric.fit.air import ROOM_AIR_DENSITY, WALL_FACTOR_U, coefficients_of

    t = np.arange(int(seconds * 1000)) / 1000.0
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.5, 4.2),
                                 gridspec_kw={"width_ratios": [1.15, 1]})
    rows = []
    for ball, mu in PHYSICS_BALLS:
        s = rollfric.thesis_setup(ball, air_density=ROOM_AIR_DENSITY)
        for deg in PHYSICS_ANGLES:
            th, om, _ = eom.solve(np.radians(deg), 0.0, mu, t, track_radius=s.track_radius,
                                  air=coefficients_of(s))
            if ball == "10mm" and deg == 20:
                span = t < 1.2
                colours = ("0.2", "#34659c", "#6d9fd6", "#c0504d", "#8a8a8a")
                terms = physics_terms(s, mu, th, om)
                for (name, term), c in zip(terms.items(), colours, strict=True):
                    ax.plot(t[span], np.maximum(term[span], 1e-9), color=c, lw=1.2, label=name)
            fit = {}
            for name, su in (("none", s.replace(air_density=0.0)), ("model", s),
                             ("hi", s.replace(air_wall_factor=s.air_wall_factor + WALL_FACTOR_U)),
                             ("lo", s.replace(air_wall_factor=s.air_wall_factor - WALL_FACTOR_U))):
                fit[name] = rollfric.fit_mu(t, th, su, checks=False).mu
            rows.append((ball, deg, 100 * (fit["none"] / mu - 1), 100 * (fit["model"] / mu - 1),
                         100 * abs(fit["hi"] - fit["lo"]) / 2 / mu))
    ax.set_yscale("log")
    ax.set_ylim(1e-6, 30)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("|term of theta''| (rad/s$^2$)")
    ax.set_title("(a) the 10 mm ball released at 20 deg, room air", fontsize=10)
    ax.legend(fontsize=7.5, loc="lower right", framealpha=0.9)
    x = np.arange(len(rows))
    bx.bar(x - 0.2, [r[2] for r in rows], 0.4, color="#c0504d", label="mu if the air is left out")
    bx.bar(x + 0.2, [r[4] for r in rows], 0.4, color="#6d9fd6",
           label="u(mu) of the drag law when it is in")
    bx.set_yscale("log")
    bx.set_xticks(x, [f"{r[0][:-2]} mm\n{r[1]} deg" for r in rows], fontsize=6.5)
    bx.set_ylabel("% of mu")
    bx.set_title("(b) the drag in mu: left out, and modelled", fontsize=10)
    bx.legend(fontsize=7.5, loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=DPI)
    plt.close(fig)
    return rows


def main() -> int:
    t0 = time.perf_counter()
    IMG.mkdir(parents=True, exist_ok=True)
    c = combine_example(IMG / "combine.png")
    print(f"combine: mu = {c.mu:.6g}, u = {c.mu_u:.2g}, Birge ratio {c.birge_ratio:.3g}")
    safety(IMG / "safety.png")
    architecture(IMG / "architecture.png")
    rollfric_inside(IMG / "rollfric.png")
    print(f"imports between the packages: {sorted(import_edges())}")
    df, setup, src = _sample_track()
    track_columns(df, IMG / "track.png")
    setup_quantities(df, setup, src, IMG / "setup.png")
    for ball, deg, none, model, u in physics(IMG / "physics.png"):
        print(f"physics: {ball} at {deg} deg: mu {none:+.3f} % without the air, "
              f"{model:+.4f} % with it, u(mu) of the drag law {u:.3f} %")
    print(f"wrote 7 figures to {IMG.relative_to(ROOT)} in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
