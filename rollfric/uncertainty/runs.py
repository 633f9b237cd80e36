"""The runs ``rollfric combine`` combines: each release's fit.json read into a :class:`Run`
(its mu, the independent part of its u, its shared budget rows with their signs and recorded
values; see :mod:`rollfric.uncertainty.combine` for the split), and the check that the runs
are of one setup.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from rollfric.errors import InputError

INDEPENDENT_SOURCES = ("statistical",)  # budget rows independent between releases
PARTS = ("shared", "independent")
FLOAT_REL = 1e-9  # setup values closer than this (relative) are the same value


@dataclasses.dataclass(frozen=True)
class Run:
    """One release: its mu, the independent part of its u and its shared rows.

    ``shared`` maps a row's source to (signed u_mu, the input's recorded value or None);
    ``law`` is fit.json's ``friction_law`` (None when it has none), ``model`` the fitted
    friction model ("coulomb", or "speed": ``mu`` is then mu0).
    """

    path: str
    mu: float
    u_independent: float
    u_mu: float
    shared: dict
    quality: str
    quality_codes: tuple
    setup: dict | None
    law: dict | None = None
    model: str = "coulomb"



def read_fit(path) -> dict:
    """A fit.json file as a dict, checked to be one of rollfric's fits with a budget.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    dict
        Its keys.

    Raises
    ------
    rollfric.errors.InputError
        If the file is missing, not JSON, not a rollfric fit.json, or has no budget.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a fit.json") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a rollfric fit.json (not a text file)") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not a rollfric fit.json (not JSON: {exc})") from None
    if not isinstance(data, dict) or not all(k in data for k in ("mu", "method", "n_samples")):
        raise InputError(f"{path}: not a rollfric fit.json (no mu, method and n_samples: "
                         "write one with rollfric measure or rollfric fit)")
    if not _number(data["mu"]):
        raise InputError(f"{path}: mu is {data['mu']!r}, not a number")
    rows = data.get("uncertainty_budget")
    if not _number(data.get("u_mu")) or not isinstance(rows, list) or not rows:
        raise InputError(f"{path}: has no uncertainty budget (fit method {data['method']!r}); "
                         "combine needs the lsq fit's budget")
    for r in rows:
        if not (isinstance(r, dict) and isinstance(r.get("source"), str)
                and _number(r.get("u_mu"))):
            raise InputError(f"{path}: a row of uncertainty_budget is not "
                             "{\"source\", ..., \"u_mu\"}: not a rollfric fit.json")
        if not 0.0 <= r["u_mu"] <= 1.0:
            raise InputError(f"{path}: budget row {r['source']!r} has u_mu = {r['u_mu']!r}, "
                             "not a standard uncertainty of mu (0 to 1)")
        if r.get("part", "shared") not in PARTS:
            raise InputError(f"{path}: budget row {r['source']!r} has part {r['part']!r}; "
                             f"it must be one of {', '.join(PARTS)}")
    return data


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def row_part(row: dict) -> str:
    """``"independent"`` or ``"shared"``: how a budget row's error relates between releases.

    Parameters
    ----------
    row : dict
        A row of fit.json's ``uncertainty_budget``; its ``part`` when it states one, else
        independent for the statistical rows (:data:`INDEPENDENT_SOURCES`), shared otherwise.

    Returns
    -------
    str
    """
    if "part" in row:
        return row["part"]
    return "independent" if row["source"] in INDEPENDENT_SOURCES else "shared"


def run_from_fit(data: dict, path) -> Run:
    """A :class:`Run` from the keys of a fit.json (:func:`read_fit`).

    Parameters
    ----------
    data : dict
        The fit.json's keys.
    path : str or os.PathLike
        Where they came from (named in messages and in the output).

    Returns
    -------
    Run

    Raises
    ------
    rollfric.errors.InputError
        If the budget has no independent part (nothing to weight the run by).
    """
    u2 = 0.0
    shared: dict = {}
    for r in data["uncertainty_budget"]:
        if row_part(r) == "independent":
            u2 += r["u_mu"] ** 2
            continue
        sign = -1.0 if _number(r.get("sensitivity")) and r["sensitivity"] < 0 else 1.0
        value = r.get("value")
        u_prev, _ = shared.get(r["source"], (0.0, None))
        shared[r["source"]] = (u_prev + sign * r["u_mu"], value if _number(value) else None)
    if not u2 > 1e-300:  # 0 (or below what its inverse square can hold)
        raise InputError(f"{path}: its budget has no statistical row (u_mu of the independent "
                         "part 0): it cannot be weighted")
    reasons = data.get("quality_reasons")
    reasons = reasons if isinstance(reasons, list) else []
    codes = tuple(str(r.get("code", "?")) if isinstance(r, dict) else str(r) for r in reasons)
    setup = data.get("setup")
    law = data.get("friction_law")
    model = "speed" if data.get("model") in ("speed", "velocity") else "coulomb"
    return Run(path=str(path), mu=float(data["mu"]), u_independent=math.sqrt(u2),
               u_mu=float(data["u_mu"]), shared=shared,
               quality=str(data.get("quality", "ok")), quality_codes=codes,
               setup=setup if isinstance(setup, dict) else None,
               law=law if isinstance(law, dict) else None, model=model)


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def same_value(a, b) -> bool:
    """Whether two recorded values (numbers, strings, lists of them) are the same, numbers
    within ``FLOAT_REL``."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b, strict=True))
    if _number(a) and _number(b):
        return math.isclose(a, b, rel_tol=FLOAT_REL, abs_tol=1e-300)
    return a == b


def setup_differences(a: dict, b: dict) -> list[str]:
    """The keys where two recorded setups (fit.json's ``setup``) differ.

    Parameters
    ----------
    a, b : dict
        Setups in the lab file's form (sections of keys,
        :meth:`rollfric.setup.model.Setup.to_toml_dict`).

    Returns
    -------
    list of str
        ``"section.key: A vs B"`` (``absent`` where one lacks the key), sorted by key; empty
        when the setups agree (numbers within a relative 1e-9).
    """
    fa, fb = _flatten(a), _flatten(b)
    out = []
    for k in sorted(set(fa) | set(fb)):
        va, vb = fa.get(k, "absent"), fb.get(k, "absent")
        if not same_value(va, vb):
            out.append(f"{k}: {va} vs {vb}")
    return out


def check_one_setup(runs: list[Run]) -> list[str]:
    """Refuse runs of different setups (ball, trough, camera); the warnings of the check.

    Runs that record their setup (fit.json's ``setup``) are compared key by key. A fit.json
    written before that record compares only through its budget: the values of the uncertain
    inputs it shares with the first run (a warning says so).

    Parameters
    ----------
    runs : list of Run
        At least one.

    Returns
    -------
    list of str
        Warnings (the runs compared without a setup record).

    Raises
    ------
    rollfric.errors.InputError
        If two runs record different setups, naming both files and the keys.
    """
    warnings = []
    first = runs[0]
    for r in runs[1:]:
        if first.setup is not None and r.setup is not None:
            diff = setup_differences(first.setup, r.setup)
        else:
            diff = [f"{s}: {first.shared[s][1]} vs {r.shared[s][1]}"
                    for s in sorted(set(first.shared) & set(r.shared))
                    if first.shared[s][1] is not None and r.shared[s][1] is not None
                    and not s.startswith("cylinder.center_px")
                    and not same_value(first.shared[s][1], r.shared[s][1])]
        if diff:
            raise InputError(f"{r.path} and {first.path} are of different setups (ball, trough "
                             f"or camera): {'; '.join(diff[:4])}"
                             + (f"; and {len(diff) - 4} more" if len(diff) > 4 else ""))
    old = [r.path for r in runs if r.setup is None]
    if old:
        warnings.append(f"{', '.join(old)}: no setup recorded (a fit.json of an earlier "
                        "rollfric): the setup compared only through the budget's uncertain "
                        "inputs; measure or fit again to compare the whole setup")
    return warnings
