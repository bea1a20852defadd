"""pimpm's own command-line options (``-pimpm_*``), read from PETSc's
options database with a message that names the option when its value is
not of the kind it takes (PETSc would only give an error code)."""
from petsc4py import PETSc

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
        raise ValueError(f"-{name} {db.getString(name, '')}: expected {expected}") from None
