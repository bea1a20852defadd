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
                          ["youngs_modulus", "poisson_ratio"]}},
     "bodies": [{"name", "material", "rigid", "geometry", "particles_per_cell",
                 "velocity", "constrain"}],
     "time": {"integrator", "dt", "end_time", "gravity"},
     "solver": {"petsc": {option: str}},
     "output": {"directory", "every"}}
"""

import copy
import difflib
import math
import numbers
import os
from collections.abc import Mapping

import yaml

__all__ = ["ConfigError", "load_config", "validate"]

# --------------------------------------------------------------------------- constants

FORMULATIONS = ("velocity", "momentum")
SHAPE_FUNCTIONS = ("linear", "gimp", "bspline")
BOUNDARY_TYPES = ("free", "fixed", "roller", "symmetry")
BOUNDARY_ALIASES = {"symmetry": "roller"}
KINEMATICS = {2: ("plane_strain", "plane_stress", "axisymmetric"), 3: ("3d",)}
MATERIAL_MODELS = ("neo_hookean", "neo_hookean_compressible", "linear_elastic", "j2_small_strain",
                   "j2_finite_strain")
GEOMETRY_TYPES = ("box", "ball", "cylinder")
INTEGRATORS = ("newmark", "quasi_static", "explicit", "backward_euler")
STRESS_UPDATES = ("musl", "usl", "usf")
AXES = ("x", "y", "z")
DEFAULT_PARTICLES_PER_CELL = 2
DEFAULT_OUTPUT_DIRECTORY = "pimpm_output"
BBOX_RELATIVE_TOLERANCE = 1e-12

TOP_KEYS = ("title", "grid", "kinematics", "materials", "bodies", "time", "solver", "output")
GRID_KEYS = ("lower", "upper", "cells", "shape_functions", "boundary")
MATERIAL_KEYS = ("model", "density", "shear_modulus", "bulk_modulus",
                 "youngs_modulus", "poisson_ratio", "yield_stress", "hardening_modulus",
                 "softening_strain", "softening_modulus")
PLASTICITY_KEYS = ("yield_stress", "hardening_modulus", "softening_strain", "softening_modulus")
BODY_KEYS = ("name", "material", "rigid", "geometry", "particles_per_cell",
             "velocity", "constrain")
GEOMETRY_KEYS = {"box": ("type", "lower", "upper"), "ball": ("type", "center", "radius"),
                 "cylinder": ("type", "lower", "upper", "axis", "center", "radius")}
TIME_KEYS = ("integrator", "dt", "end_time", "gravity", "dt_initial", "ramp_factor",
             "max_cuts", "easy_newton_iterations", "max_particle_displacement", "cfl",
             "stress_update", "formulation")
SOLVER_KEYS = ("preset", "fallback", "convergence", "petsc")
CONVERGENCE_KEYS = ("test", "displacement_tolerance", "energy_tolerance")
SOLVER_PRESETS = ("mumps", "cg-gamg", "gmres-gamg", "jfnk", "matrix-free")
CONVERGENCE_TESTS = ("petsc", "guilkey_weiss")
OUTPUT_KEYS = ("directory", "every")

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
        x = float(value)
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


def _optional_mapping(value):
    return {} if value is _MISSING else value


# --------------------------------------------------------------------------- sections

def _validate_grid(value, path):
    sec = _Section(value, path, GRID_KEYS)
    lower = _float_vector(sec.required("lower", "a list of 2 or 3 numbers"), sec.sub("lower"), None)
    dim = len(lower)
    upper = _float_vector(sec.required("upper", f"a list of {dim} numbers"), sec.sub("upper"), dim)
    for i in range(dim):
        if not upper[i] > lower[i]:
            _fail(f"{sec.sub('upper')}[{i}]", upper[i],
                  f"a number > {sec.sub('lower')}[{i}] = {_fmt(lower[i])}")
    cells_path = sec.sub("cells")
    cells_raw = sec.required("cells", f"a list of {dim} integers >= 1")
    if not isinstance(cells_raw, (list, tuple)) or len(cells_raw) != dim:
        _fail(cells_path, cells_raw, f"a list of {dim} integers >= 1")
    cells = [_int(c, f"{cells_path}[{i}]") for i, c in enumerate(cells_raw)]

    shape = sec.optional("shape_functions")
    shape = "linear" if shape is _MISSING else _enum(shape, sec.sub("shape_functions"),
                                                     SHAPE_FUNCTIONS)

    faces = [f"{AXES[a]}{side}" for a in range(dim) for side in ("min", "max")]
    bsec = _Section(_optional_mapping(sec.optional("boundary")), sec.sub("boundary"), faces)
    boundary = {}
    for face in faces:
        b = bsec.optional(face)
        if b is _MISSING:
            boundary[face] = "free"
        else:
            b = _enum(b, bsec.sub(face), BOUNDARY_TYPES)
            boundary[face] = BOUNDARY_ALIASES.get(b, b)
    grid = {"lower": lower, "upper": upper, "cells": cells, "shape_functions": shape,
            "boundary": boundary}
    return grid, dim


def _validate_material(value, path):
    sec = _Section(value, path, MATERIAL_KEYS)
    model = _enum(sec.required("model", _choices(MATERIAL_MODELS)), sec.sub("model"),
                  MATERIAL_MODELS)
    density = _positive(sec.required("density", "a positive number"), sec.sub("density"))
    out = {"model": model, "density": density}

    given = [k for k in ("shear_modulus", "bulk_modulus", "youngs_modulus", "poisson_ratio")
             if sec.has(k)]
    vals = {}
    for key in given:
        if key == "poisson_ratio":
            expected = "a number strictly between -1 and 0.5"
            nu = _float(sec.data[key], sec.sub(key), expected)
            if not -1.0 < nu < 0.5:
                _fail(sec.sub(key), sec.data[key], expected)
            vals[key] = nu
        else:
            vals[key] = _positive(sec.data[key], sec.sub(key))
    pairs = "exactly one pair of elastic constants: shear_modulus + bulk_modulus, " \
            "or youngs_modulus + poisson_ratio"
    if set(given) == {"shear_modulus", "bulk_modulus"}:
        out["shear_modulus"] = vals["shear_modulus"]
        out["bulk_modulus"] = vals["bulk_modulus"]
    elif set(given) == {"youngs_modulus", "poisson_ratio"}:
        E, nu = vals["youngs_modulus"], vals["poisson_ratio"]
        out["shear_modulus"] = E / (2.0 * (1.0 + nu))
        out["bulk_modulus"] = E / (3.0 * (1.0 - 2.0 * nu))
        out["youngs_modulus"] = E
        out["poisson_ratio"] = nu
    else:
        have = ", ".join(given) if given else "no elastic constants"
        raise ConfigError(f"{path} has {have}: expected {pairs}", path=path)
    if model in ("j2_small_strain", "j2_finite_strain"):
        out["yield_stress"] = _positive(sec.required("yield_stress", "a positive number"),
                                        sec.sub("yield_stress"))
        for key, default in (("hardening_modulus", 0.0), ("softening_modulus", 0.0)):
            v = sec.optional(key)
            out[key] = default if v is _MISSING else _float(v, sec.sub(key), "a number")
        v = sec.optional("softening_strain")
        out["softening_strain"] = None if v is _MISSING else _positive(v, sec.sub("softening_strain"))
    else:
        for key in PLASTICITY_KEYS:
            if sec.has(key):
                _fail(sec.sub(key), sec.data[key], "plasticity parameters only with a j2 model")
    return out


def _validate_materials(value, path):
    if value is None or not isinstance(value, Mapping) or not value:
        _fail(path, value, "a non-empty mapping of material name -> material spec")
    out = {}
    for name, spec in value.items():
        if not isinstance(name, str) or not name.strip():
            _fail(path, name, "material names to be non-empty strings")
        out[name] = _validate_material(spec, _join(path, name))
    return out


def _validate_geometry(value, path, dim):
    if not isinstance(value, Mapping):
        _fail(path, value, f"a mapping with key 'type' ({_choices(GEOMETRY_TYPES)})")
    if "type" not in value:
        _fail_missing(_join(path, "type"), _choices(GEOMETRY_TYPES))
    gtype = _enum(value["type"], _join(path, "type"), GEOMETRY_TYPES)
    sec = _Section(value, path, GEOMETRY_KEYS[gtype])
    if gtype in ("box", "cylinder"):
        lower = _float_vector(sec.required("lower", f"a list of {dim} numbers"),
                              sec.sub("lower"), dim)
        upper = _float_vector(sec.required("upper", f"a list of {dim} numbers"),
                              sec.sub("upper"), dim)
        for i in range(dim):
            if not upper[i] > lower[i]:
                _fail(f"{sec.sub('upper')}[{i}]", upper[i],
                      f"a number > {sec.sub('lower')}[{i}] = {_fmt(lower[i])}")
        if gtype == "box":
            return {"type": "box", "lower": lower, "upper": upper}
        # cylinder (3D): the part of the box within radius of the axis line through center
        if dim != 3:
            _fail(_join(path, "type"), gtype, "a cylinder only in 3D (use a box or a ball in 2D)")
        axis = _enum(sec.required("axis", _choices(AXES)), sec.sub("axis"), AXES)
        center = _float_vector(sec.required("center", "a list of 3 numbers"), sec.sub("center"), dim)
        radius = _positive(sec.required("radius", "a positive number"), sec.sub("radius"))
        return {"type": "cylinder", "lower": lower, "upper": upper, "axis": axis,
                "center": center, "radius": radius}
    center = _float_vector(sec.required("center", f"a list of {dim} numbers"),
                           sec.sub("center"), dim)
    radius = _positive(sec.required("radius", "a positive number"), sec.sub("radius"))
    return {"type": "ball", "center": center, "radius": radius}


def _check_inside_grid(geom, path, grid, dim):
    glo, ghi = grid["lower"], grid["upper"]
    for i in range(dim):
        tol = BBOX_RELATIVE_TOLERANCE * (ghi[i] - glo[i])
        axis = AXES[i]
        within = f"the grid on axis {axis} ([{_fmt(glo[i])}, {_fmt(ghi[i])}])"
        if geom["type"] in ("box", "cylinder"):
            if geom["lower"][i] < glo[i] - tol:
                _fail(f"{path}.lower[{i}]", geom["lower"][i],
                      f"a number >= grid.lower[{i}] = {_fmt(glo[i])} (the body must lie "
                      f"within {within})")
            if geom["upper"][i] > ghi[i] + tol:
                _fail(f"{path}.upper[{i}]", geom["upper"][i],
                      f"a number <= grid.upper[{i}] = {_fmt(ghi[i])} (the body must lie "
                      f"within {within})")
        else:
            c, r = geom["center"][i], geom["radius"]
            if c - r < glo[i] - tol or c + r > ghi[i] + tol:
                _fail(path, geom,
                      f"the ball (center +- radius, here [{_fmt(c - r)}, {_fmt(c + r)}] on "
                      f"axis {axis}) to lie within {within}")


def _validate_body(value, path, dim, materials, grid):
    sec = _Section(value, path, BODY_KEYS)
    name = _string(sec.required("name", "a non-empty string"), sec.sub("name"))

    rigid = sec.optional("rigid")
    rigid = False if rigid is _MISSING else _bool(rigid, sec.sub("rigid"))

    known = ", ".join(materials)
    material = sec.data.get("material", _MISSING)
    if material is _MISSING or (material is None and rigid):
        if not rigid:
            _fail_missing(sec.sub("material"), f"the name of a material: {known}")
        material = None
    else:
        if not isinstance(material, str) or material not in materials:
            _fail(sec.sub("material"), material, f"the name of a material: {known}")

    geometry = _validate_geometry(sec.required("geometry", f"a mapping with key 'type' "
                                                           f"({_choices(GEOMETRY_TYPES)})"),
                                  sec.sub("geometry"), dim)
    _check_inside_grid(geometry, sec.sub("geometry"), grid, dim)

    ppc_path = sec.sub("particles_per_cell")
    ppc = sec.optional("particles_per_cell")
    if ppc is _MISSING:
        ppc = [DEFAULT_PARTICLES_PER_CELL] * dim
    elif isinstance(ppc, (list, tuple)):
        if len(ppc) != dim:
            _fail(ppc_path, ppc, f"an integer >= 1 or a list of {dim} integers >= 1")
        ppc = [_int(n, f"{ppc_path}[{i}]") for i, n in enumerate(ppc)]
    else:
        if not _is_int(ppc) or ppc < 1:
            _fail(ppc_path, ppc, f"an integer >= 1 or a list of {dim} integers >= 1")
        ppc = [int(ppc)] * dim

    velocity = sec.optional("velocity")
    velocity = [0.0] * dim if velocity is _MISSING else \
        _float_vector(velocity, sec.sub("velocity"), dim)

    axes = AXES[:dim]
    con_path = sec.sub("constrain")
    if not rigid:
        if sec.has("constrain"):
            _fail(con_path, sec.data["constrain"],
                  "no 'constrain' on a deformable body (it applies only with rigid: true)")
        constrain = None
    else:
        con = sec.optional("constrain")
        expected = f"a non-empty list of distinct axes among {', '.join(axes)}"
        if con is _MISSING:
            constrain = list(axes)
        else:
            if not isinstance(con, (list, tuple)) or not con:
                _fail(con_path, con, expected)
            seen = set()
            for i, a in enumerate(con):
                if not isinstance(a, str) or a not in axes:
                    _fail(f"{con_path}[{i}]", a, _choices(axes))
                if a in seen:
                    _fail(f"{con_path}[{i}]", a, f"{expected} (duplicate {a!r})")
                seen.add(a)
            constrain = [a for a in axes if a in seen]

    return {"name": name, "material": material, "rigid": rigid, "geometry": geometry,
            "particles_per_cell": ppc, "velocity": velocity, "constrain": constrain}


def _validate_bodies(value, path, dim, materials, grid):
    if not isinstance(value, (list, tuple)) or not value:
        _fail(path, value, "a non-empty list of bodies")
    bodies, first = [], {}
    for i, spec in enumerate(value):
        bpath = f"{path}[{i}]"
        body = _validate_body(spec, bpath, dim, materials, grid)
        if body["name"] in first:
            _fail(f"{bpath}.name", body["name"],
                  f"a unique body name (already used by {path}[{first[body['name']]}])")
        first[body["name"]] = i
        bodies.append(body)
    if all(b["rigid"] for b in bodies):
        _fail(path, [b["name"] for b in bodies],
              "at least one deformable body (rigid: false); all bodies are rigid")
    return bodies


def _validate_time(value, path, dim):
    sec = _Section(value, path, TIME_KEYS)
    integ = sec.optional("integrator")
    integ = "newmark" if integ is _MISSING else _enum(integ, sec.sub("integrator"), INTEGRATORS)
    explicit = integ == "explicit"
    if explicit and sec.optional("dt") is _MISSING:
        dt = None                     # automatic: cfl * h / (wave speed + |v|) every step
    else:
        dt = _positive(sec.required("dt", "a positive number"), sec.sub("dt"))
    end_raw = sec.required("end_time", "a positive number >= time.dt")
    end_time = _positive(end_raw, sec.sub("end_time"))
    if dt is not None and end_time < dt:
        _fail(sec.sub("end_time"), end_raw, f"a number >= time.dt = {_fmt(dt)}")
    cfl = sec.optional("cfl")
    cfl = 0.5 if cfl is _MISSING else _float(cfl, sec.sub("cfl"), "a number in (0, 1]")
    if not 0.0 < cfl <= 1.0:
        _fail(sec.sub("cfl"), cfl, "a number in (0, 1]")
    update = sec.optional("stress_update")
    update = "musl" if update is _MISSING else _enum(update, sec.sub("stress_update"), STRESS_UPDATES)
    for key in ("cfl", "stress_update"):
        if sec.has(key) and not explicit:
            _fail(sec.sub(key), sec.data[key], "to be given only with time.integrator: explicit")
    formulation = sec.optional("formulation")
    formulation = "velocity" if formulation is _MISSING else _enum(
        formulation, sec.sub("formulation"), FORMULATIONS)
    if sec.has("formulation") and explicit:
        _fail(sec.sub("formulation"), sec.data["formulation"],
              "to be given only with an implicit integrator (explicit MPM uses time.stress_update; "
              "musl is the explicit momentum formulation)")
    if formulation == "momentum" and integ == "quasi_static":
        _fail(sec.sub("formulation"), sec.data["formulation"],
              "'velocity' with time.integrator: quasi_static (the momentum formulation needs "
              "inertia: without the mass term its tangent K R is singular wherever the "
              "particles do not determine the nodal values)")
    gravity = sec.optional("gravity")
    gravity = [0.0] * dim if gravity is _MISSING else \
        _float_vector(gravity, sec.sub("gravity"), dim)
    dt_initial = sec.optional("dt_initial")
    dt_initial = dt if dt_initial is _MISSING else _positive(dt_initial, sec.sub("dt_initial"))
    if dt is not None and dt_initial > dt:
        _fail(sec.sub("dt_initial"), dt_initial, f"a number <= time.dt = {_fmt(dt)}")
    ramp = sec.optional("ramp_factor")
    ramp = 1.2 if ramp is _MISSING else _float(ramp, sec.sub("ramp_factor"), "a number >= 1")
    if ramp < 1.0:
        _fail(sec.sub("ramp_factor"), ramp, "a number >= 1")
    cuts = sec.optional("max_cuts")
    cuts = 4 if cuts is _MISSING else _int(cuts, sec.sub("max_cuts"), minimum=0)
    easy = sec.optional("easy_newton_iterations")
    easy = 6 if easy is _MISSING else _int(easy, sec.sub("easy_newton_iterations"), minimum=1)
    limit = sec.optional("max_particle_displacement")
    limit = None if limit is _MISSING else _positive(limit, sec.sub("max_particle_displacement"))
    return {"integrator": integ, "dt": dt, "end_time": end_time, "gravity": gravity,
            "dt_initial": dt_initial, "ramp_factor": ramp, "max_cuts": cuts,
            "easy_newton_iterations": easy, "max_particle_displacement": limit,
            "cfl": cfl, "stress_update": update, "formulation": formulation}


def _petsc_value(value, path):
    if value is None:
        return ""  # option without a value (a flag, e.g. ksp_monitor)
    if isinstance(value, bool):
        return "true" if value else "false"
    if _is_int(value):
        return str(int(value))
    if _is_number(value):
        return repr(float(value))
    if isinstance(value, str):
        return value
    _fail(path, value, "a scalar option value (string, number, boolean or empty)")


def _validate_solver(value, path):
    sec = _Section(_optional_mapping(value), path, SOLVER_KEYS)
    raw = _optional_mapping(sec.optional("petsc"))
    ppath = sec.sub("petsc")
    if not isinstance(raw, Mapping):
        _fail(ppath, raw, "a mapping of PETSc option names to values")
    petsc = {}
    for key, val in raw.items():
        kpath = _join(ppath, key)
        if not isinstance(key, str):
            _fail(kpath, key, "a PETSc option name (a string)")
        name = key.strip().lstrip("-")
        if not name or any(ch.isspace() for ch in name):
            _fail(kpath, key, "a PETSc option name without spaces, e.g. snes_rtol")
        if name in petsc:
            _fail(kpath, key, f"each PETSc option given once ({name!r} is repeated)")
        petsc[name] = _petsc_value(val, kpath)
    preset = sec.optional("preset")
    preset = "mumps" if preset is _MISSING else _enum(preset, sec.sub("preset"), SOLVER_PRESETS)
    fallback = sec.optional("fallback")
    fallback = True if fallback is _MISSING else _bool(fallback, sec.sub("fallback"))
    conv = _Section(_optional_mapping(sec.optional("convergence")), sec.sub("convergence"),
                    CONVERGENCE_KEYS)
    test = conv.optional("test")
    test = "petsc" if test is _MISSING else _enum(test, conv.sub("test"), CONVERGENCE_TESTS)
    tols = {}
    for key, default in (("displacement_tolerance", 1e-6), ("energy_tolerance", 1e-12)):
        v = conv.optional(key)
        tols[key] = default if v is _MISSING else _positive(v, conv.sub(key))
    return {"preset": preset, "fallback": fallback,
            "convergence": dict(test=test, **tols), "petsc": petsc}


def _validate_output(value, path, source_name):
    sec = _Section(_optional_mapping(value), path, OUTPUT_KEYS)
    directory = sec.optional("directory")
    if directory is _MISSING:
        directory = f"{source_name}_output" if source_name else DEFAULT_OUTPUT_DIRECTORY
    else:
        directory = _string(directory, sec.sub("directory"), "a non-empty directory path")
    every = sec.optional("every")
    every = 1 if every is _MISSING else _int(every, sec.sub("every"))
    return {"directory": directory, "every": every}


# --------------------------------------------------------------------------- public API

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

    grid, dim = _validate_grid(top.required("grid", "a mapping with lower, upper, cells"),
                               "grid")

    kin = top.optional("kinematics")
    if kin is _MISSING:
        kin = KINEMATICS[dim][0]
    else:
        kin = _enum(kin, "kinematics", KINEMATICS[dim], f" (for dim = {dim})")

    materials = _validate_materials(
        top.required("materials", "a non-empty mapping of material name -> material spec"),
        "materials")
    bodies = _validate_bodies(top.required("bodies", "a non-empty list of bodies"),
                              "bodies", dim, materials, grid)
    time = _validate_time(top.required("time", "a mapping with dt and end_time"), "time", dim)
    solver = _validate_solver(top.optional("solver"), "solver")
    output = _validate_output(top.optional("output"), "output", source_name)

    return {"title": title, "dim": dim, "grid": grid, "kinematics": kin,
            "materials": materials, "bodies": bodies, "time": time, "solver": solver,
            "output": output}


def load_config(path):
    """Read a YAML input file and return ``validate(raw, source_name=<file stem>)``.

    A missing/unreadable file, a YAML syntax error, a duplicated key and every validation
    problem raise :class:`ConfigError`, prefixed with the file name and, when known,
    the line (``billet.yaml:12: materials.rubber.density = -1.0: expected ...``).
    """
    fname = os.fspath(path)
    try:
        with open(fname, "r", encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise ConfigError(f"{fname}: file not found: expected an existing YAML input file") \
            from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{fname}: cannot read file ({err.__class__.__name__}: {err}): "
                          f"expected a readable UTF-8 YAML input file") from None

    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        raw = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(_yaml_error_message(fname, err)) from None

    lines = {}
    if node is not None:
        _index_nodes(node, ROOT, lines, fname, set())

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


# --------------------------------------------------------------------------- YAML helpers

def _yaml_error_message(fname, err):
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    where = f"{fname}:{mark.line + 1}:{mark.column + 1}" if mark is not None else fname
    parts = [p for p in (getattr(err, "context", None), getattr(err, "problem", None)) if p]
    detail = "; ".join(parts) if parts else str(err)
    return f"{where}: YAML syntax error: {detail}"


def _index_nodes(node, path, lines, fname, active):
    """Record the 1-based line of every key path; reject duplicated mapping keys."""
    if id(node) in active:  # recursive alias
        return
    lines.setdefault(path, node.start_mark.line + 1)
    active = active | {id(node)}
    if isinstance(node, yaml.MappingNode):
        seen = {}
        for knode, vnode in node.value:
            if not isinstance(knode, yaml.ScalarNode) or knode.tag == "tag:yaml.org,2002:merge":
                continue
            key = knode.value
            kpath = key if path == ROOT else f"{path}.{key}"
            if key in seen:
                raise ConfigError(
                    f"{fname}:{knode.start_mark.line + 1}: {kpath} is given twice (first on "
                    f"line {seen[key]}): expected each key once per mapping",
                    path=kpath)
            seen[key] = knode.start_mark.line + 1
            lines.setdefault(kpath, knode.start_mark.line + 1)
            _index_nodes(vnode, kpath, lines, fname, active)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _index_nodes(item, f"{path}[{i}]", lines, fname, active)


def _line_for(path, lines):
    """Line of the longest prefix of ``path`` found in the YAML file, or None."""
    while path:
        if path in lines:
            return lines[path]
        cut = max(path.rfind("."), path.rfind("["))
        if cut <= 0:
            break
        path = path[:cut]
    return lines.get(path) if path else None
