"""Input file reading and validation for pimpm.

``load_config(path)`` reads a YAML input file and returns the normalized configuration
dict produced by ``validate(raw)``.  Every problem is reported as a :class:`ConfigError`
whose message is a single line naming the key path (``bodies[1].geometry.upper``), the
offending value and what was expected.  The schema is documented in ``docs/INPUT.md``.

The normalized dict has every default filled in, floats as ``float``, integers as ``int``,
vectors as lists of length ``dim``, and an extra top-level key ``dim`` (2 or 3)::

    {"title": str, "dim": int,
     "grid": {"lower", "upper", "cells", "shape_functions", "boundary", "weak_node_fraction"},
     "kinematics": str,
     "materials": {name: {"model", "density", "shear_modulus", "bulk_modulus",
                          ["youngs_modulus", "poisson_ratio"], <the model's parameters>}},
     "bodies": [{"name", "material", "rigid", "geometry", "particles_per_cell",
                 "velocity", "constrain"}],
     "contact": [{"bodies": [name, name], "law", ["friction_coefficient"]}],
     "time": {"integrator", "dt", "end_time", "gravity", "dt_initial", "ramp_factor",
              "max_cuts", "easy_newton_iterations", "max_particle_displacement", "cfl",
              "stress_update", "formulation", <the integrator's parameters>},
     "solver": {"preset", "fallback", "convergence", "petsc": {option: str}, "free_dofs_only",
                "reuse_factorization", "linear_predictor"},
     "parallel": {"balance", "rebalance_threshold"},
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
from .pairs import _validate_contact_pairs, check_contact_pairs
from .checks import _MISSING, ROOT, ConfigError, _enum, _fail, _Section
from .schema import DEFAULT_F_BAR, DEFAULT_F_BAR_BLEND, KINEMATICS, TOP_KEYS
from .sections import _validate_grid, _validate_output, _validate_parallel, _validate_solver, _validate_time
from .yaml_input import _line_for, parse_text, read_yaml

__all__ = ["ConfigError", "load_config", "validate"]


def validate(raw, source_name=None, base_dir=None):
    """Validate a raw (YAML-loaded) config and return a new normalized dict.

    ``source_name`` (the input file's stem) sets the default output directory
    ``<source_name>_output``; without it the default is ``pimpm_output``.
    ``base_dir``: where relative paths of geometry files start (load_config:
    the input file's directory; default the working directory).
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
    if kin == "axisymmetric" and grid["lower"][0] < 0.0:
        # x is the radius: a body at negative r has a negative volume (issue 32: it ran,
        # with zero Newton iterations and a negative strain energy)
        _fail("grid.lower", grid["lower"], "x >= 0 with kinematics: axisymmetric (x is the radius r)")

    materials = _validate_materials(
        top.required("materials", "a non-empty mapping of material name -> material spec"),
        "materials")
    bodies = _validate_bodies(top.required("bodies", "a non-empty list of bodies"),
                              "bodies", dim, materials, grid, functions, base_dir)
    pairs = _validate_contact_pairs(top.optional("contact"), "contact", bodies)
    loads = _validate_loads(top.optional("loads"), "loads", dim, bodies, functions, grid)
    time = _validate_time(top.required("time", "a mapping with dt and end_time"), "time", dim,
                          functions)
    solver = _validate_solver(top.optional("solver"), "solver")
    parallel = _validate_parallel(top.optional("parallel"), "parallel", explicit=time["integrator"] == "explicit")
    output = _validate_output(top.optional("output"), "output", source_name)

    config = {"title": title, "dim": dim, "functions": functions, "grid": grid, "kinematics": kin,
              "materials": materials, "bodies": bodies, "contact": pairs, "loads": loads, "time": time,
              "solver": solver, "parallel": parallel, "output": output}
    resolve_f_bar(config)
    check_derived(config)
    _check_contact(config)
    check_contact_pairs(config)
    _check_f_bar(config)
    return config


def resolve_f_bar(config):
    """Each material's ``f_bar`` where it does not say (None): DEFAULT_F_BAR;
    and its ``f_bar_blend`` where it does not say (DEFAULT_F_BAR_BLEND of
    its average). A blend given with F-bar off is refused."""
    for name, material in config["materials"].items():
        if material.get("f_bar") is None:
            material["f_bar"] = DEFAULT_F_BAR
        if material["f_bar"]:
            if material.get("f_bar_blend") is None:
                material["f_bar_blend"] = DEFAULT_F_BAR_BLEND[material["f_bar"]]
        elif material.get("f_bar_blend") is not None:
            path = f"materials.{name}.f_bar_blend"
            raise ConfigError(f"{path} = {material['f_bar_blend']:g}: expected no f_bar_blend while "
                              f"materials.{name}.f_bar is false (f_bar: cells or nodes averages the "
                              "volume change)", path=path)
        else:
            material.pop("f_bar_blend", None)


def _check_f_bar(config):
    """F-bar (pimpm.kernels.fbar) averages the volume change of each cell:
    plane stress has no volumetric constraint to lock (the thickness
    adjusts), and the momentum formulation's tangent keeps the DMDA's
    stencil, which the cell coupling outgrows. Every averaged material of a
    run averages the same way."""
    averages = {}
    for name, material in config["materials"].items():
        if not material.get("f_bar"):
            continue
        path = f"materials.{name}.f_bar"
        averages.setdefault(material["f_bar"], name)
        if len(averages) > 1:
            (kind, first), = [(k, v) for k, v in averages.items() if k != material["f_bar"]]
            raise ConfigError(f"{path} = {material['f_bar']}: expected {kind}, as materials.{first}.f_bar "
                              "(the materials of a run average their volume change the same way)", path=path)
        if config["kinematics"] == "plane_stress":
            raise ConfigError(f"{path} = {material['f_bar']}: expected false with kinematics: plane_stress (plane stress "
                              "does not lock volumetrically: the thickness stretch takes up the volume "
                              "change)", path=path)
        if config["time"].get("formulation") == "momentum":
            raise ConfigError(f"{path} = {material['f_bar']}: expected false with time.formulation: momentum (F-bar "
                              "runs in the velocity formulation)", path=path)


def _check_contact(config):
    """Unilateral and frictional contact (pimpm.terms.contact) runs in the
    velocity formulation (implicit and explicit); say so for the momentum
    formulation."""
    time = config["time"]
    for i, body in enumerate(config["bodies"]):
        law = body.get("contact")
        if law in (None, "bonded"):
            continue
        if time["formulation"] != "velocity":
            raise ConfigError(f"bodies[{i}].contact = {law!r}: expected bonded with "
                              f"time.formulation: {time['formulation']} (frictionless, friction and tied "
                              "contact need the velocity formulation)", path=f"bodies[{i}].contact")


def load_config(path, overrides=()):
    """Read a YAML input file and return ``validate(raw, source_name=<file stem>)``.

    ``overrides``: ``KEY.PATH=VALUE`` strings (the command line's ``--set``),
    applied to the file's data before validation; VALUE is read as YAML
    (``0.0025``, ``[160, 84]``, ``{type: ramp, start: 0, end: 1}``) and
    validated exactly as if it were in the file.

    A missing/unreadable file, a YAML syntax error, a duplicated key and every validation
    problem raise :class:`ConfigError`, prefixed with the file name and, when known,
    the line (``billet.yaml:12: materials.rubber.density = -1.0: expected ...``), or
    with the ``--set`` that gave the value.
    """
    fname = os.fspath(path)
    raw, lines = read_yaml(fname)

    if raw is None:
        raise ConfigError(f"{fname}: the file is empty: expected a YAML mapping with the "
                          f"sections {', '.join(TOP_KEYS)}")
    given = apply_overrides(raw, overrides)
    stem = os.path.splitext(os.path.basename(fname))[0]
    try:
        return validate(raw, source_name=stem,
                        base_dir=os.path.dirname(os.path.abspath(fname)))
    except ConfigError as err:
        for key, text in given:
            if err.path and (err.path == key or err.path.startswith(key + ".")
                             or err.path.startswith(key + "[")):
                raise ConfigError(f"--set {text}: {err}", path=err.path) from None
        line = _line_for(err.path, lines)
        where = f"{fname}:{line}" if line else fname
        raise ConfigError(f"{where}: {err}", path=err.path) from None


def _parse_key(text):
    """``bodies[0].velocity`` -> ['bodies', 0, 'velocity']; None if malformed."""
    keys = []
    for part in text.split("."):
        name, _, rest = part.partition("[")
        if not name and not keys:
            return None
        if name:
            keys.append(name)
        while rest:
            index, close, rest = rest.partition("]")
            if not close or not index.isdigit() or (rest and not rest.startswith("[")):
                return None
            keys.append(int(index))
            rest = rest[1:] if rest else ""
    return keys if keys and all(k != "" for k in keys) else None


def apply_overrides(raw, overrides):
    """Set each ``KEY.PATH=VALUE`` in ``raw`` (in place); returns [(normalized
    key path, the override's text)]. ConfigError for a malformed one."""
    given = []
    for text in overrides:
        key, eq, value_text = text.partition("=")
        keys = _parse_key(key.strip()) if eq else None
        if keys is None:
            raise ConfigError(f"--set {text}: expected KEY.PATH=VALUE, e.g. time.dt=0.0025 or "
                              f"bodies[0].velocity=[0,-1]")
        # the limits of input files hold here too (issue 32: '&a [*a]' recursed, an
        # alias bomb grew without bound)
        shown = text if len(text) <= 80 else text[:77] + "..."
        value = parse_text(f"--set {shown}: the value", value_text)[0] if value_text.strip() else None
        node = raw
        for depth, k in enumerate(keys[:-1]):
            where = ".".join(str(x) for x in keys[:depth + 1])
            if isinstance(k, int):
                if not isinstance(node, list) or k >= len(node):
                    raise ConfigError(f"--set {text}: {where} is not an existing list entry: expected "
                                      f"an index below the list's length")
                node = node[k]
            else:
                if not isinstance(node, dict):
                    raise ConfigError(f"--set {text}: {where} is inside a value that is not a mapping")
                if node.get(k) is None:
                    node[k] = {}
                node = node[k]
        last = keys[-1]
        if isinstance(last, int):
            if not isinstance(node, list) or last >= len(node):
                raise ConfigError(f"--set {text}: expected an index below the list's length")
            node[last] = value
        else:
            if not isinstance(node, dict):
                raise ConfigError(f"--set {text}: its parent is not a mapping")
            node[last] = value
        path = ""
        for k in keys:
            path = f"{path}[{k}]" if isinstance(k, int) else (f"{path}.{k}" if path else k)
        given.append((path, text))
    return given
