"""One declarative schema for the project's TOML files (setups, scenarios, cases, sweeps).

Each file's sections and keys are declared once, as data: a :class:`Key` states a key's kind,
its unit (the conversion to SI), its range, its default, whether it takes a ``K_u`` standard
uncertainty and the names it allows; a :class:`Schema` maps section names to their keys. One
checker (:func:`check_file`, :func:`check_table`, :func:`check_value`) reads a parsed table
against them and raises the file's :class:`~rollfric.errors.InputError` subclass in the file's
own wording (:class:`Messages`). Rules that join several keys (a ball that must fit the trough)
stay as small named functions beside each file's schema.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from rollfric.errors import InputError

# The range of each quantity (SI) that a real trough, ball and camera can have: generous, but a
# value outside it is a typing or unit mistake (1e300 for the gravity, fps in kHz, ...) that
# would only overflow the fit. sim's scenarios use the same ranges.
PLAUSIBLE = {  # name -> (lowest, highest, SI unit)
    "cylinder_radius": (1e-4, 100.0, "m"),
    "ball_diameter": (1e-6, 100.0, "m"),
    "ball_mass": (1e-12, 1e6, "kg"),
    "fps": (1e-3, 1e8, "Hz"),
    "pixel_size": (1e-9, 1.0, "m"),
    "gravity": (0.01, 1000.0, "m/s^2"),  # the Moon's 1.62, Jupiter's 24.8
    "air_density": (0.0, 10.0, "kg/m^3"),  # a vacuum .. pressurised air; not a liquid
    "air_viscosity": (1e-6, 1e-3, "Pa s"),
    "air_cd": (1e-3, 100.0, "1"),
}


def check_plausible(name: str, value: float, error: type[InputError] = InputError,
                    label: str | None = None, scale: float = 1.0, unit: str | None = None
                    ) -> float:
    """``value`` if it lies in the plausible range of ``name`` (:data:`PLAUSIBLE`, SI).

    Parameters
    ----------
    name : str
        The quantity (a key of :data:`PLAUSIBLE`).
    value : float
        Its value in SI units.
    error : type
        The InputError subclass raised when the value is outside the range.
    label, scale, unit : str, float, str
        How the message names the quantity, and the factor and unit it is shown in (default:
        ``name`` in SI units).

    Returns
    -------
    float
        ``value``.
    """
    lo, hi, si = PLAUSIBLE[name]
    if not lo <= value <= hi:
        u = si if unit is None else unit
        raise error(f"{label or name} = {value * scale:g} {u} is outside the plausible range "
                    f"{lo * scale:g}..{hi * scale:g} {u}")
    return value


@dataclasses.dataclass(frozen=True)
class Unit:
    """A lab unit and its conversion to SI.

    ``factor``: SI per lab unit (to SI as ``value * factor``); ``per``: lab units per SI unit
    (back to the lab unit as ``value * per``, and to SI as ``value / per`` where ``exact``: a
    typed decimal then converts exactly, 85.3 mm -> 0.0853 m). Degrees convert to radians.
    """

    name: str
    factor: float = 1.0
    per: float = 1.0
    exact: bool = False

    def to_si(self, value: float) -> float:
        """The lab-unit ``value`` in SI units."""
        if self.name == "deg":
            return math.radians(value)
        return float(value) / self.per if self.exact else float(value) * self.factor


NONE = Unit("")
MM = Unit("mm", 1e-3, 1e3)
GRAM = Unit("g", 1e-3, 1e3)
BENCH_MM = Unit("mm", 1e-3, 1000.0, exact=True)  # sim's scenarios: exact for typed decimals
BENCH_GRAM = Unit("g", 1e-3, 1000.0, exact=True)
DEG = Unit("deg")

# The kinds of value a key may hold: name -> accepted Python types (bool is never a number).
KINDS: dict[str, tuple[type, ...]] = {
    "number": (int, float), "float": (float,), "int": (int,), "str": (str,), "bool": (bool,),
    "list": (list,), "table": (dict,), "pair": (list,), "any": (object,),
}


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


MISSING: Any = _Missing()  # a key's default when it has none: absent keys are left out


@dataclasses.dataclass(frozen=True)
class Key:
    """One key of a TOML table, declared as data.

    Attributes
    ----------
    name : str
        The key as the file writes it (``radius_mm``).
    kind : str or tuple of str
        A kind of :data:`KINDS` (a tuple: any of them); ``"pair"`` is two finite numbers.
    field : str or None
        The name it is returned under (default: ``name``).
    unit : Unit
        Its lab unit, converted to SI on reading.
    required : bool
        A file without it is refused.
    default : object
        The value returned when it is absent (default: left out of the result).
    sign : str
        ``">0"`` or ``">=0"``: the numbers allowed, besides finite ones.
    plausible : str or None
        The quantity of :data:`PLAUSIBLE` whose range the SI value must lie in.
    bounds : tuple or None
        (lowest, highest), inclusive, of the value as written.
    choices : tuple
        The values allowed (strings), if only some.
    uncertain : bool or str
        True: the key takes a ``K_u`` partner, its standard uncertainty in the same unit;
        ``"own"``: its ``_u`` partner is read with it elsewhere.
    hint : str or None
        How every message about a bad value says what is wanted (``"must be [x, y] in
        pixels"``), instead of the :class:`Messages` wording.
    read : bool
        False: only its name is checked here; another reader reads its value (and it is left
        out of what :func:`read_section` returns).
    """

    name: str
    kind: str | tuple[str, ...] = "number"
    field: str | None = None
    unit: Unit = NONE
    required: bool = False
    default: Any = MISSING
    sign: str = ""
    plausible: str | None = None
    bounds: tuple | None = None
    choices: tuple = ()
    uncertain: bool | str = False
    hint: str | None = None
    read: bool = True

    @property
    def target(self) -> str:
        """The name the value is returned under."""
        return self.field or self.name

    @property
    def kinds(self) -> tuple[str, ...]:
        return self.kind if isinstance(self.kind, tuple) else (self.kind,)


@dataclasses.dataclass(frozen=True)
class Messages:
    """A file's wording of each fault, as ``str.format`` templates.

    The fields ``{source}`` (where the file came from), ``{section}``, ``{key}``, ``{value}``,
    ``{known}`` (the names allowed), ``{kind}`` (what was wanted) and ``{sign}`` (the range
    wanted: ``sign_words``) are filled in.
    ``kind_names``: how ``{kind}`` names a kind (absent: the Python type's name).
    """

    unknown_section: str = "{source}: unknown section [{section}] (known: {known})"
    missing_section: str = "{source}: missing section [{section}]"
    not_table: str = "{source}: [{section}] must be a table"
    unknown_key: str = "{source}: unknown key {section}.{key} (known: {known})"
    missing_key: str = "{source}: missing key {section}.{key}"
    kind: str = "{source}: {section}.{key} must be {kind}, got {value!r}"
    # None: any float is taken (a later check of the value decides)
    finite: str | None = "{source}: {section}.{key} must be finite, got {value!r}"
    sign: str = "{source}: {section}.{key} must be positive, got {value!r}"
    choice: str = "{source}: {section}.{key} must be one of {known}, got {value!r}"
    hint: str = "{source}: {section}.{key} {hint}, got {value!r}"
    label: str = "{source}: {section}.{key}"  # how a range's message names the key
    kind_names: tuple = (("number", "a number"), ("str", "a string"))
    sign_words: tuple = ((">0", "positive"), (">=0", ">= 0"))  # {sign} in the sign message


@dataclasses.dataclass(frozen=True)
class Schema:
    """A file's sections (name -> its keys, in the order they are checked) and its wording.

    ``required``: the sections a file must have; ``uncertain_note``: what an unknown key's
    message adds when the file's keys take ``K_u`` partners (empty: they take none, and a
    ``K_u`` key is unknown).
    """

    sections: dict
    error: type[InputError] = InputError
    messages: Messages = Messages()
    required: tuple = ()
    uncertain_note: str = ""

    def keys(self, section: str) -> dict:
        """The keys of ``section``: name -> :class:`Key`."""
        return {k.name: k for k in self.sections[section]}


def _fail(schema: Schema, template: str, **fields) -> InputError:
    return schema.error(template.format(**fields))


def _kind_name(schema: Schema, kinds: tuple[str, ...]) -> str:
    names = dict(schema.messages.kind_names)
    return " or ".join(names.get(k, KINDS[k][0].__name__) for k in kinds)


def _is_kind(value: Any, kind: str) -> bool:
    if kind in ("number", "float"):  # a float key takes an int too (as float)
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "pair":
        return isinstance(value, list) and len(value) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in value)
    return isinstance(value, KINDS[kind])


def check_value(schema: Schema, section: str, key: Key, value: Any, source: str) -> Any:
    """One present value checked against its :class:`Key` and converted to SI.

    Parameters
    ----------
    schema : Schema
        The file's schema (its error class and wording).
    section : str
        The section the key is in, for the message.
    key : Key
        The declaration.
    value : object
        The value as parsed.
    source : str
        Where the file came from, for the message.

    Returns
    -------
    object
        The value: a number as float in SI units, a pair as a tuple of floats, else as given.

    Raises
    ------
    InputError
        ``schema.error``, in the schema's wording, for a value of another kind, a non-finite
        or out-of-range number or a name not allowed.
    """
    m = schema.messages
    where = {"source": source, "section": section, "key": key.name, "value": value}

    def bad(template: str, **more) -> InputError:
        if key.hint is not None:
            return _fail(schema, m.hint, hint=key.hint, **where)
        return _fail(schema, template, **where, **more)

    if not any(_is_kind(value, k) for k in key.kinds):
        raise bad(m.kind, kind=_kind_name(schema, key.kinds))
    if key.kinds == ("float",) and isinstance(value, int):
        value = float(value)
    if key.choices and value not in key.choices:
        raise bad(m.choice, known=", ".join(map(str, key.choices)))
    if "any" in key.kinds:
        return value  # read by its own reader
    if key.kinds == ("pair",):
        return tuple(float(v) for v in value)
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    if numeric and m.finite is not None and key.kinds != ("int",) \
            and not math.isfinite(value):
        raise bad(m.finite)
    if numeric and ((key.sign == ">0" and value <= 0) or (key.sign == ">=0" and value < 0)):
        raise bad(m.sign, sign=dict(m.sign_words)[key.sign])
    if numeric and key.bounds is not None and not key.bounds[0] <= value <= key.bounds[1]:
        raise bad(m.sign, sign=f"{key.bounds[0]}..{key.bounds[1]}")
    if not numeric or key.kinds == ("int",) or "bool" in key.kinds:
        return value
    si = key.unit.to_si(value)
    if key.plausible is not None:
        check_plausible(key.plausible, si, schema.error, m.label.format(**where),
                        key.unit.per, key.unit.name or PLAUSIBLE[key.plausible][2])
    return si


def check_names(schema: Schema, data: dict, source: str, extra: tuple = ()) -> None:
    """Refuse an unknown or missing section, a section that is not a table, an unknown or
    missing key; a ``K_u`` key is checked against its partner (:func:`check_partners`).

    ``extra``: further sections allowed (named last in the message), read by their own reader.
    """
    m = schema.messages
    known = [*schema.sections, *extra]
    for section in data:
        if section not in known:
            raise _fail(schema, m.unknown_section, source=source, section=section,
                        known=", ".join(known))
    for section in schema.required:
        if section not in data:
            raise _fail(schema, m.missing_section, source=source, section=section)
    for section, table in data.items():
        if not isinstance(table, dict):
            raise _fail(schema, m.not_table, source=source, section=section, value=table)
        if section in schema.sections:
            check_table(schema, section, table, source)


def check_table(schema: Schema, section: str, table: dict, source: str) -> None:
    """Refuse an unknown or missing key of one section (its ``K_u`` partners checked too)."""
    m = schema.messages
    keys = schema.keys(section)
    for name in table:
        base = name[:-2] if name.endswith("_u") else None
        if base is not None and base in keys and schema.uncertain_note:
            check_partner(schema, section, keys[base], table, source)
            continue
        if name not in keys:
            raise _fail(schema, m.unknown_key, source=source, section=section, key=name,
                        known=", ".join(keys) + schema.uncertain_note)
    for name, key in keys.items():
        if key.required and name not in table:
            raise _fail(schema, m.missing_key, source=source, section=section, key=name)


def uncertain_keys(schema: Schema) -> list[tuple[str, Key]]:
    """The (section, key) of every key that takes a ``K_u`` partner of its own."""
    return [(section, key) for section, keys in schema.sections.items() for key in keys
            if key.uncertain is True]


def check_partner(schema: Schema, section: str, key: Key, table: dict, source: str) -> None:
    """A ``K_u`` key needs its ``K``, and ``K`` must take an uncertainty."""
    k = f"{key.name}_u"
    if key.uncertain == "own":
        if key.name not in table:
            raise schema.error(f"{source}: {section}.{k} (its standard uncertainties) is given "
                               f"without {section}.{key.name}")
        return  # read with its key, by that key's reader
    if key.name not in table:
        raise schema.error(f"{source}: {section}.{k} (a standard uncertainty) is given without "
                           f"{section}.{key.name}")
    if not key.uncertain:
        raise schema.error(f"{source}: {section}.{k}: no standard uncertainty is taken for "
                           f"{section}.{key.name} (only for " + ", ".join(
                               f"{sec}.{u.name}" for sec, u in uncertain_keys(schema)) + ")")


def check_uncertainty(schema: Schema, section: str, key: Key, value: Any, source: str
                      ) -> float | tuple[float, float]:
    """The ``K_u`` partner of ``key``: a number >= 0 in the key's unit, or (``"pair"`` keys)
    one for each of the pair (a single number: the same for both); returned in SI units
    (a pair as given)."""
    where = f"{source}: {section}.{key.name}_u"
    if key.kinds == ("pair",):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value, value]
        if (not isinstance(value, list) or len(value) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           for v in value)):
            raise schema.error(f"{where} must be [ux, uy] in pixels, got {value!r}")
        vals = [float(v) for v in value]
    else:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise schema.error(f"{where} must be a number, got {value!r}")
        vals = [float(value)]
    if not all(math.isfinite(v) and v >= 0 for v in vals):
        raise schema.error(f"{where} (a standard uncertainty) must be finite and >= 0, "
                           f"got {value!r}")
    return tuple(vals) if key.kinds == ("pair",) else vals[0] / key.unit.per


def read_section(schema: Schema, section: str, table: dict, source: str) -> dict:
    """The values of one section's present keys (and the defaults of absent ones), checked
    and in SI units, under their :attr:`Key.target` names, in the order declared."""
    out = {}
    for key in schema.sections[section]:
        if not key.read:
            continue
        if key.name in table:
            out[key.target] = check_value(schema, section, key, table[key.name], source)
        elif key.default is not MISSING:
            out[key.target] = key.default
    return out


def check_section(schema: Schema, section: str, table: Any, source: str) -> dict:
    """One section checked (a table, its keys known and present as required) and read
    (:func:`read_section`)."""
    if not isinstance(table, dict):
        raise _fail(schema, schema.messages.not_table, source=source, section=section,
                    value=table)
    check_table(schema, section, table, source)
    return read_section(schema, section, table, source)


def check_file(schema: Schema, data: dict, source: str, extra: tuple = ()) -> dict:
    """A whole file checked (:func:`check_names`) and read (:func:`read_section`).

    Parameters
    ----------
    schema : Schema
        The file's declaration.
    data : dict
        The parsed TOML.
    source : str
        Where it came from, for the messages.
    extra : tuple of str
        Sections allowed besides the schema's, left to their own readers.

    Returns
    -------
    dict
        Target name -> value (SI), for every section of the schema.
    """
    check_names(schema, data, source, extra)
    out: dict = {}
    for section in schema.sections:
        out.update(read_section(schema, section, data.get(section, {}), source))
    return out
