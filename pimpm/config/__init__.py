"""Input file reading and validation for pimpm.

``load_config(path)`` reads a YAML input file and returns the normalized configuration
dict produced by ``validate(raw)``.  Every problem is reported as a :class:`ConfigError`
whose message is a single line naming the key path (``bodies[1].geometry.upper``), the
offending value and what was expected.  The schema is documented in ``docs/INPUT.md``.

The normalized dict has every default filled in, floats as ``float``, integers as ``int``,
vectors as lists of length ``dim``, and an extra top-level key ``dim`` (2 or 3)::

    {"title": str, "dim": int,
     "grid": {"lower", "upper", "cells", "shape_functions", "boundary"},
     "kinematics": str,
     "materials": {name: {"model", "density", "shear_modulus", "bulk_modulus",
                          ["youngs_modulus", "poisson_ratio"], <the model's parameters>}},
     "bodies": [{"name", "material", "rigid", "geometry", "particles_per_cell",
                 "velocity", "constrain"}],
     "time": {"integrator", "dt", "end_time", "gravity", "dt_initial", "ramp_factor",
              "max_cuts", "easy_newton_iterations", "max_particle_displacement", "cfl",
              "stress_update", "formulation", <the integrator's parameters>},
     "solver": {"preset", "fallback", "convergence", "petsc": {option: str}},
     "output": {"directory", "every"}}

Modules: :mod:`.schema` (the keys and names), :mod:`.checks` (the error and the
value checks), :mod:`.sections` (grid, time, solver, output), :mod:`.bodies`
(materials, geometries, bodies), :mod:`.yaml_input` (YAML helpers). A model's
and an integrator's own parameters come from their registries.
"""
import copy
import os

from .bodies import _validate_bodies, _validate_materials
from .derived import check_derived
from .functions import _validate_functions
from .loads import _validate_loads
from .checks import _MISSING, ROOT, ConfigError, _enum, _fail, _Section
from .schema import KINEMATICS, TOP_KEYS
from .sections import _validate_grid, _validate_output, _validate_solver, _validate_time
from .yaml_input import _line_for, read_yaml

__all__ = ["ConfigError", "load_config", "validate"]


def validate(raw, source_name=None):
    """Validate a raw (YAML-loaded) config and return a new normalized dict.

    ``source_name`` (the input file's stem) sets the default output directory
    ``<source_name>_output``; without it the default is ``pimpm_output``.
    ``raw`` is never modified.  Raises :class:`ConfigError` on the first problem found.
    """
    raw = copy.deepcopy(raw)  # never touch the caller's data, never alias it
    top = _Section(raw, ROOT, TOP_KEYS,
                   what=f"a mapping with keys among {', '.join(TOP_KEYS)}")

    title = top.optional("title")
    title = "" if title is _MISSING else title
    if not isinstance(title, str):
        _fail("title", title, "a string")

    functions = _validate_functions(top.optional("functions"))
    grid, dim = _validate_grid(top.required("grid", "a mapping with lower, upper, cells"),
                               "grid", functions)

    kin = top.optional("kinematics")
    if kin is _MISSING:
        kin = KINEMATICS[dim][0]
    else:
        kin = _enum(kin, "kinematics", KINEMATICS[dim], f" (for dim = {dim})")

    materials = _validate_materials(
        top.required("materials", "a non-empty mapping of material name -> material spec"),
        "materials")
    bodies = _validate_bodies(top.required("bodies", "a non-empty list of bodies"),
                              "bodies", dim, materials, grid, functions)
    loads = _validate_loads(top.optional("loads"), "loads", dim, bodies, functions, grid)
    time = _validate_time(top.required("time", "a mapping with dt and end_time"), "time", dim,
                          functions)
    solver = _validate_solver(top.optional("solver"), "solver")
    output = _validate_output(top.optional("output"), "output", source_name)

    config = {"title": title, "dim": dim, "functions": functions, "grid": grid, "kinematics": kin,
              "materials": materials, "bodies": bodies, "loads": loads, "time": time,
              "solver": solver, "output": output}
    check_derived(config)
    return config


def load_config(path):
    """Read a YAML input file and return ``validate(raw, source_name=<file stem>)``.

    A missing/unreadable file, a YAML syntax error, a duplicated key and every validation
    problem raise :class:`ConfigError`, prefixed with the file name and, when known,
    the line (``billet.yaml:12: materials.rubber.density = -1.0: expected ...``).
    """
    fname = os.fspath(path)
    raw, lines = read_yaml(fname)

    if raw is None:
        raise ConfigError(f"{fname}: the file is empty: expected a YAML mapping with the "
                          f"sections {', '.join(TOP_KEYS)}")
    stem = os.path.splitext(os.path.basename(fname))[0]
    try:
        return validate(raw, source_name=stem)
    except ConfigError as err:
        line = _line_for(err.path, lines)
        where = f"{fname}:{line}" if line else fname
        raise ConfigError(f"{where}: {err}", path=err.path) from None
