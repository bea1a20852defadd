"""pimpm's own command-line options (``-pimpm_*``), read from PETSc's
options database with a message that names the option when its value is
not of the kind it takes (PETSc would only give an error code)."""
from petsc4py import PETSc

from .presets import shown

_KINDS = {bool: ("getBool", "true or false (1 or 0)"), float: ("getReal", "a number"),
          int: ("getInt", "an integer"), str: ("getString", "a word")}


def pimpm_option(name, default, kind=None):
    """The value of ``-name`` (``default`` when absent); ValueError naming the
    option and its value when PETSc cannot read it as ``kind`` (the
    default's type unless given)."""
    kind = kind or type(default)
    getter, expected = _KINDS[kind]
    db = PETSc.Options()
    try:
        return getattr(db, getter)(name, default)
    except PETSc.Error:
        raise ValueError(f"-{name} {shown(db.getString(name, ''))}: expected {expected}") from None


#: -pimpm_* options that are aliases of input keys: option -> (section, key, kind)
INPUT_ALIASES = {"pimpm_weak_node_fraction": ("grid", "weak_node_fraction", float),
                 "pimpm_free_dofs_only": ("solver", "free_dofs_only", bool),
                 "pimpm_reuse_factorization": ("solver", "reuse_factorization", bool),
                 "pimpm_linear_predictor": ("solver", "linear_predictor", bool),
                 "pimpm_fallback_max_dofs": ("solver", "fallback_max_dofs", int),
                 "pimpm_balance": ("parallel", "balance", bool),
                 "pimpm_rebalance_threshold": ("parallel", "rebalance_threshold", float)}


def with_command_line(config):
    """The validated input with the command line's ``-pimpm_*`` aliases
    (:data:`INPUT_ALIASES`) applied and checked as the input's keys are
    (ValueError naming the option): the run's effective settings, which a
    checkpoint records with the input."""
    db = PETSc.Options()
    out = dict(config)
    for option, (section, key, kind) in INPUT_ALIASES.items():
        if not db.hasName(option):
            continue
        default = config[section][key]
        value = pimpm_option(option, default if isinstance(default, kind) else kind(), kind)
        given = f"-{option} {shown(db.getString(option, ''))}"
        if key == "weak_node_fraction" and not 0.0 <= value < 1.0:
            raise ValueError(f"{given}: expected a number >= 0 and < 1 (0: no extension)")
        if key == "fallback_max_dofs" and not value >= 1:
            raise ValueError(f"{given}: expected an integer >= 1")
        if key == "rebalance_threshold" and not value >= 1.0:
            raise ValueError(f"{given}: expected a number >= 1")
        out[section] = dict(out[section], **{key: value})
    return out
