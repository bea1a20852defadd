"""Validation building blocks: the one-line :class:`ConfigError`, value
formatting, scalar and vector checks, and :class:`_Section` (a mapping
with known keys)."""
import difflib
import math
import numbers
from collections.abc import Mapping

ROOT = "(top level)"
_MISSING = object()


# --------------------------------------------------------------------------- errors

class ConfigError(Exception):
    """Bad input.

    ``str(err)`` is one line naming the key path, the value and what was expected, e.g.
    ``"materials.rubber.shear_modulus = -6000000.0: expected a positive number"``.
    ``err.path`` is the key path (or None for file-level problems).
    """

    def __init__(self, message, path=None):
        message = str(message).replace("\r\n", " ").replace("\n", " ").replace("\r", " ")
        super().__init__(message)
        self.path = path


def _fmt(value, limit=160):
    """Compact one-line rendering of a (YAML-ish) value for error messages."""
    text = _fmt_inner(value)
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    return text


def _fmt_inner(value):
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, numbers.Integral):
        digits = str(abs(int(value)))
        if len(digits) > 24:                  # an integer beyond the float range: its size, not its digits
            return f"{'-' if value < 0 else ''}{digits[0]}.{digits[1:4]}e+{len(digits) - 1} (an integer)"
        return str(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt_inner(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_key_str(k)}: {_fmt_inner(v)}" for k, v in value.items()) + "}"
    return repr(value)


def _key_str(key):
    return key if isinstance(key, str) else _fmt_inner(key)


def _fail(path, value, expected):
    raise ConfigError(f"{path} = {_fmt(value)}: expected {expected}", path=path)


def _fail_missing(path, expected):
    raise ConfigError(f"{path} is missing: expected {expected} (required key)", path=path)


def _join(path, key):
    key = _key_str(key)
    return key if path in ("", ROOT) else f"{path}.{key}"


def _choices(options):
    return "one of " + ", ".join(str(o) for o in options)


# --------------------------------------------------------------------------- scalar checks

def _is_number(value):
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _is_int(value):
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _float(value, path, expected="a number"):
    """A finite float; accepts ints and strings that parse as floats ("6.0e6")."""
    if _is_number(value):
        try:
            x = float(value)
        except OverflowError:            # an integer beyond the double range
            _fail(path, value, expected)
    elif isinstance(value, str):
        try:
            x = float(value.strip())
        except ValueError:
            _fail(path, value, expected)
    else:
        _fail(path, value, expected)
    if not math.isfinite(x):
        _fail(path, value, expected)
    return x


def _positive(value, path):
    expected = "a positive number"
    x = _float(value, path, expected)
    if x <= 0.0:
        _fail(path, value, expected)
    return x


def _int(value, path, minimum=1):
    expected = f"an integer >= {minimum}"
    if not _is_int(value) or int(value) < minimum:
        _fail(path, value, expected)
    return int(value)


def _bool(value, path):
    if not isinstance(value, bool):
        _fail(path, value, "true or false")
    return value


def _string(value, path, expected="a non-empty string"):
    if not isinstance(value, str) or not value.strip():
        _fail(path, value, expected)
    return value


def _name(value, path):
    """A name that heads history.csv's columns and labels output: a non-empty
    string without control characters (a newline would break the header)."""
    expected = "a non-empty name without control characters"
    if not isinstance(value, str) or not value.strip() or any(ord(c) < 32 or ord(c) == 127 for c in value):
        _fail(path, value, expected)
    return value


def _enum(value, path, options, note=""):
    if not isinstance(value, str) or value not in options:
        _fail(path, value, _choices(options) + note)
    return value


def _float_vector(value, path, dim, name="numbers"):
    if dim is None:
        expected = f"a list of 2 or 3 {name}"
    else:
        expected = f"a list of {dim} {name}"
    if not isinstance(value, (list, tuple)):
        _fail(path, value, expected)
    if (dim is None and len(value) not in (2, 3)) or (dim is not None and len(value) != dim):
        _fail(path, value, expected)
    return [_float(v, f"{path}[{i}]") for i, v in enumerate(value)]


# --------------------------------------------------------------------------- mappings

class _Section:
    """A validated mapping: checks its type and that it has only allowed keys."""

    def __init__(self, value, path, allowed, what=None):
        if not isinstance(value, Mapping):
            _fail(path, value, what or f"a mapping with keys among {', '.join(allowed)}")
        for key in value:
            if key not in allowed:
                hint = ""
                if isinstance(key, str):
                    close = difflib.get_close_matches(key, allowed, n=1)
                    if close:
                        hint = f" (did you mean {close[0]!r}?)"
                keypath = _join(path, key)
                raise ConfigError(
                    f"{keypath} = {_fmt(value[key])}: unknown key; expected one of the "
                    f"allowed keys: {', '.join(allowed)}{hint}", path=keypath)
        self.data = value
        self.path = path

    def sub(self, key):
        return _join(self.path, key)

    def has(self, key):
        return key in self.data

    def optional(self, key):
        """The value or _MISSING when absent; null counts as absent (default applies)."""
        value = self.data.get(key, _MISSING)
        return _MISSING if value is None else value

    def required(self, key, expected):
        if key not in self.data:
            _fail_missing(self.sub(key), expected)
        return self.data[key]


def _ordered_bounds(sec, dim):
    """``lower`` and ``upper`` of section ``sec``: lists of ``dim`` numbers
    with upper > lower on every axis."""
    lower = _float_vector(sec.required("lower", f"a list of {dim} numbers"), sec.sub("lower"), dim)
    upper = _float_vector(sec.required("upper", f"a list of {dim} numbers"), sec.sub("upper"), dim)
    for i in range(dim):
        if not upper[i] > lower[i]:
            _fail(f"{sec.sub('upper')}[{i}]", upper[i], f"a number > {sec.sub('lower')}[{i}] = {_fmt(lower[i])}")
    return lower, upper


def _optional_mapping(value):
    return {} if value is _MISSING else value
