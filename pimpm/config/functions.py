"""Validation of the ``functions`` section (named functions of time; the
runtime objects are :mod:`pimpm.functions`) and of references to them."""
from collections.abc import Mapping

from .checks import (_MISSING, _Section, _choices, _enum, _fail, _float, _join, _optional_mapping,
                     _string)

FUNCTION_TYPES = ("table", "constant", "ramp")
FUNCTION_KEYS = {"table": ("type", "points"), "constant": ("type", "value"),
                 "ramp": ("type", "start", "end", "from", "to")}


def _validate_functions(value, path="functions"):
    """name -> {"type": "table", "points": [[t, f], ...]} (every shorthand
    normalized to its table)."""
    value = _optional_mapping(value)
    if not isinstance(value, Mapping):
        _fail(path, value, "a mapping of function name -> function")
    out = {}
    for name, spec in value.items():
        fpath = _join(path, name)
        if not isinstance(name, str) or not name.strip():
            _fail(path, name, "function names to be non-empty strings")
        if not isinstance(spec, Mapping) or "type" not in spec:
            _fail(fpath, spec, f"a mapping with key 'type' ({_choices(FUNCTION_TYPES)})")
        kind = _enum(spec["type"], _join(fpath, "type"), FUNCTION_TYPES)
        sec = _Section(spec, fpath, FUNCTION_KEYS[kind])
        if kind == "constant":
            points = [[0.0, _float(sec.required("value", "a number"), sec.sub("value"))]]
        elif kind == "ramp":
            start = _float(sec.required("start", "a number (a time)"), sec.sub("start"))
            end = _float(sec.required("end", "a number > start"), sec.sub("end"))
            if not end > start:
                _fail(sec.sub("end"), sec.data["end"], f"a number > {fpath}.start = {start!r}")
            low = sec.optional("from")
            high = sec.optional("to")
            low = 0.0 if low is _MISSING else _float(low, sec.sub("from"))
            high = 1.0 if high is _MISSING else _float(high, sec.sub("to"))
            points = [[start, low], [end, high]]
        else:
            raw = sec.required("points", "a non-empty list of [time, value] pairs")
            ppath = sec.sub("points")
            if not isinstance(raw, (list, tuple)) or not raw:
                _fail(ppath, raw, "a non-empty list of [time, value] pairs")
            points = []
            for i, pair in enumerate(raw):
                if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                    _fail(f"{ppath}[{i}]", pair, "a [time, value] pair of numbers")
                t = _float(pair[0], f"{ppath}[{i}][0]", "a finite number (a time)")
                f = _float(pair[1], f"{ppath}[{i}][1]", "a finite number")
                if points and t < points[-1][0]:
                    _fail(f"{ppath}[{i}][0]", pair[0],
                          f"times in increasing order (a time >= {points[-1][0]!r}, the time before it)")
                points.append([t, f])
        out[name] = {"type": "table", "points": points}
    return out


def _function_ref(value, path, functions):
    """A reference ``function: NAME`` to a defined function (None if absent)."""
    if value is _MISSING or value is None:
        return None
    name = _string(value, path, "the name of a function defined under functions")
    if name not in functions:
        known = ", ".join(functions) if functions else "none is defined"
        _fail(path, value, f"the name of a function defined under functions ({known})")
    return name
