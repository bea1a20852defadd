"""Validation of materials (each model's parameters from its own table),
geometries and bodies. Geometries from files (meshes, particle clouds) are
read and checked here, so that a bad file is bad input (exit 2) before
anything is allocated or written."""
import os
from collections.abc import Mapping

import numpy as np

from ..materials import MODELS, REQUIRED, elastic_moduli
from .checks import (ConfigError, _MISSING, _Section, _bool, _choices, _enum, _fail,
    _fail_missing, _float, _float_vector, _fmt, _int, _is_int, _join, _name, _ordered_bounds, _positive, _string)
from .functions import _function_ref
from .schema import (AXES, BBOX_RELATIVE_TOLERANCE, BODY_KEYS, DEFAULT_PARTICLES_PER_CELL,
    CONTACT_GEOMETRIES, TOOL_LAWS, DEFAULT_CONTACT_STIFFNESS, DEFAULT_SLIP_TOLERANCE, DEFAULT_TANGENTIAL_STIFFNESS, DEFAULT_PARTICLES_PER_ELEMENT, ELASTIC_KEYS, FILE_GEOMETRIES, GEOMETRY_KEYS, GEOMETRY_TYPES, MATERIAL_KEYS, MATERIAL_MODELS,
    MODEL_PARAMETER_KEYS, RIGID_ONLY_GEOMETRIES, F_BAR_AVERAGES)


def _f_bar(value, path):
    """``f_bar``: false, true (the first of F_BAR_AVERAGES) or an average's
    name; returns False or the average's name."""
    if isinstance(value, str) and value in F_BAR_AVERAGES:
        return value
    if isinstance(value, bool):
        return F_BAR_AVERAGES[0] if value else False
    _fail(path, value, "true, false, " + " or ".join(F_BAR_AVERAGES))


def _validate_material(value, path):
    sec = _Section(value, path, MATERIAL_KEYS)
    model = _enum(sec.required("model", _choices(MATERIAL_MODELS)), sec.sub("model"),
                  MATERIAL_MODELS)
    density = _positive(sec.required("density", "a positive number"), sec.sub("density"))
    out = {"model": model, "density": density}
    f_bar = sec.optional("f_bar")
    # None: not given, decided with the kinematics (pimpm.config.resolve_f_bar)
    out["f_bar"] = None if f_bar is _MISSING else _f_bar(f_bar, sec.sub("f_bar"))
    blend = sec.optional("f_bar_blend")
    out["f_bar_blend"] = None
    if blend is not _MISSING:
        expected = "a number from 0 to less than 1"
        out["f_bar_blend"] = _float(blend, sec.sub("f_bar_blend"), expected)
        if not 0.0 <= out["f_bar_blend"] < 1.0:
            _fail(sec.sub("f_bar_blend"), blend, expected)

    given = [k for k in ELASTIC_KEYS if sec.has(k)]
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
        out["shear_modulus"], out["bulk_modulus"] = elastic_moduli(vals)
        out["youngs_modulus"] = vals["youngs_modulus"]
        out["poisson_ratio"] = vals["poisson_ratio"]
    else:
        have = ", ".join(given) if given else "no elastic constants"
        raise ConfigError(f"{path} has {have}: expected {pairs}", path=path)
    parameters = MODELS[model].parameters          # the model's own parameter table
    for key, parameter in parameters.items():
        expected = "a positive number" if parameter.positive else "a number"
        if parameter.default is REQUIRED:
            v = sec.required(key, expected)
        else:
            v = sec.optional(key)
            if v is _MISSING:
                out[key] = parameter.default
                continue
        out[key] = _positive(v, sec.sub(key)) if parameter.positive else _float(v, sec.sub(key), expected)
    for key in MODEL_PARAMETER_KEYS:
        if key not in parameters and sec.has(key):
            takers = ", ".join(name for name, m in MODELS.items() if key in m.parameters)
            _fail(sec.sub(key), sec.data[key], f"{key} only with a model that takes it ({takers})")
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


def _validate_file_geometry(sec, gtype, path, dim, base_dir):
    """A mesh or particle file: read, checked, summarized (the particles are
    made by :mod:`pimpm.meshes` at seeding)."""
    from .. import meshes
    fpath, given, out = _geometry_file(sec, gtype, dim, base_dir)
    file, scale, offset = out["file"], out["scale"], out["offset"]
    try:
        if gtype == "mesh":
            n = sec.optional("particles_per_element")
            n = DEFAULT_PARTICLES_PER_ELEMENT if n is _MISSING else \
                _int(n, sec.sub("particles_per_element"))
            if n > 20:
                _fail(sec.sub("particles_per_element"), n, "an integer from 1 to 20 (per axis "
                      "and element)")
            mesh = meshes.read_mesh(file, dim)
            bad = meshes.check_orientation(mesh, 1)
            if bad is not None:
                index, cell_type, value, count = bad
                measure = "area" if dim == 2 else "volume"
                raise meshes.GeometryFileError(
                    f"has {count} inverted or degenerate element(s), the first {cell_type} "
                    f"{index} with det J {value:.6g}: expected a positive {measure} for every "
                    f"element (counter-clockwise nodes in 2D, right-handed in 3D)")
            elements, count, volume, lower, upper = meshes.mesh_summary(mesh, n, scale, offset)
            out.update(particles_per_element=n, elements=int(elements))
        else:
            x, vol = meshes.read_particle_file(file, dim)
            x = x * scale + np.asarray(offset)
            count, volume = len(x), float(np.sum(vol)) * scale ** dim
            lower, upper = x.min(axis=0), x.max(axis=0)
        out.update(particles=int(count), volume=float(volume),
                   lower=[float(v) for v in lower], upper=[float(v) for v in upper],
                   sha256=meshes.file_digest(file))
    except meshes.GeometryFileError as err:
        shown = given if given == file else f"{given} ({file})"
        raise ConfigError(f"{fpath} = {shown!r}: {err}", path=fpath) from None
    except OSError as err:
        raise ConfigError(f"{fpath} = {given!r}: cannot be read ({err.strerror})", path=fpath) from None
    return out


_FILE_KINDS = {"mesh": "the path of a mesh file", "particles": "the path of a CSV or HDF5 particle file",
               "surface": "the path of a surface mesh file (lines in 2D, triangles in 3D)"}


def _geometry_file(sec, gtype, dim, base_dir):
    """(key path, the file as given, {type, file (absolute), scale, offset})."""
    fpath = sec.sub("file")
    given = _string(sec.required("file", _FILE_KINDS[gtype]), fpath)
    file = os.path.normpath(os.path.join(base_dir or os.getcwd(), os.path.expanduser(given)))
    scale = sec.optional("scale")
    scale = 1.0 if scale is _MISSING else _positive(scale, sec.sub("scale"))
    offset = sec.optional("offset")
    offset = [0.0] * dim if offset is _MISSING else _float_vector(offset, sec.sub("offset"), dim)
    return fpath, given, {"type": gtype, "file": file, "scale": scale, "offset": offset}


def _validate_surface_geometry(sec, path, dim, base_dir):
    """A rigid tool's surface mesh (pimpm.surfaces): read, checked (facets,
    orientation), summarized; ``flip_normals`` reverses every facet."""
    from .. import meshes, surfaces
    fpath, given, out = _geometry_file(sec, "surface", dim, base_dir)
    flip = sec.optional("flip_normals")
    out["flip_normals"] = False if flip is _MISSING else _bool(flip, sec.sub("flip_normals"))
    try:
        points, facets = surfaces.surface_of(out, dim)
        surfaces.check_surface(points, facets)
        out.update(facets=int(len(facets)), sha256=meshes.file_digest(out["file"]),
                   bounds=[[float(v) for v in points.min(axis=0)], [float(v) for v in points.max(axis=0)]])
    except meshes.GeometryFileError as err:
        shown = given if given == out["file"] else f"{given} ({out['file']})"
        raise ConfigError(f"{fpath} = {shown!r}: {err}", path=fpath) from None
    except OSError as err:
        raise ConfigError(f"{fpath} = {given!r}: cannot be read ({err.strerror})", path=fpath) from None
    return out


def _validate_geometry(value, path, dim, base_dir=None):
    if not isinstance(value, Mapping):
        _fail(path, value, f"a mapping with key 'type' ({_choices(GEOMETRY_TYPES)})")
    if "type" not in value:
        _fail_missing(_join(path, "type"), _choices(GEOMETRY_TYPES))
    gtype = _enum(value["type"], _join(path, "type"), GEOMETRY_TYPES)
    sec = _Section(value, path, GEOMETRY_KEYS[gtype])
    if gtype == "surface":
        return _validate_surface_geometry(sec, path, dim, base_dir)
    if gtype in FILE_GEOMETRIES:
        return _validate_file_geometry(sec, gtype, path, dim, base_dir)
    if gtype == "half_space":
        # the points x with (x - point) . normal <= 0; the normal points out of the tool
        point = _float_vector(sec.required("point", f"a list of {dim} numbers"), sec.sub("point"), dim)
        normal = _float_vector(sec.required("normal", f"a list of {dim} numbers, not all zero"),
                               sec.sub("normal"), dim)
        length = float(np.linalg.norm(normal))
        if not length > 0.0:
            _fail(sec.sub("normal"), sec.data["normal"], f"a list of {dim} numbers, not all zero (the "
                                             "outward normal of the tool's surface)")
        return {"type": "half_space", "point": point, "normal": [v / length for v in normal]}
    if gtype in ("box", "cylinder"):
        lower, upper = _ordered_bounds(sec, dim)
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
        if geom["type"] in FILE_GEOMETRIES:
            lo, hi = geom["lower"][i], geom["upper"][i]
            if lo < glo[i] - tol or hi > ghi[i] + tol:
                what = "mesh" if geom["type"] == "mesh" else "particles"
                raise ConfigError(
                    f"{path}.file = {geom['file']!r}: the {what} (after scale and offset) spans "
                    f"[{_fmt(lo)}, {_fmt(hi)}] on axis {axis}: expected it to lie within {within}",
                    path=f"{path}.file")
        elif geom["type"] in ("half_space", "surface"):
            continue                    # clipped to the grid (bodies: lower/upper set within the grid's)
        elif geom["type"] in ("box", "cylinder"):
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


def _validate_body(value, path, dim, materials, grid, functions=None, base_dir=None):
    sec = _Section(value, path, BODY_KEYS)
    name = _name(sec.required("name", "a non-empty string"), sec.sub("name"))

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
                                  sec.sub("geometry"), dim, base_dir)
    _check_inside_grid(geometry, sec.sub("geometry"), grid, dim)
    if geometry["type"] in RIGID_ONLY_GEOMETRIES:
        if not rigid:
            _fail(sec.sub("geometry.type"), geometry["type"], f"a {geometry['type']} only on a rigid body "
                  "(rigid: true): a deformable body needs a bounded region")
        geometry["lower"], geometry["upper"] = list(grid["lower"]), list(grid["upper"])
        if geometry["type"] == "surface":       # its particles (for show): inside it, within a cell of it
            spacing = [(u - lo) / n for lo, u, n in zip(grid["lower"], grid["upper"], grid["cells"])]
            low, high = geometry.pop("bounds")
            geometry["lower"] = [max(g, v - h) for g, v, h in zip(grid["lower"], low, spacing)]
            geometry["upper"] = [min(g, v + h) for g, v, h in zip(grid["upper"], high, spacing)]

    ppc_path = sec.sub("particles_per_cell")
    ppc = sec.optional("particles_per_cell")
    if geometry["type"] in FILE_GEOMETRIES and ppc is not _MISSING:
        instead = ("geometry.particles_per_element" if geometry["type"] == "mesh"
                   else "the particles of the file")
        _fail(ppc_path, ppc, f"no particles_per_cell with a {geometry['type']} geometry "
                             f"(it uses {instead})")
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
    function = _function_ref(sec.optional("function"), sec.sub("function"), functions or {})
    if function is not None and not rigid:
        _fail(sec.sub("function"), function, "a function only on a rigid body (a deformable body's "
                                             "velocity is its initial velocity)")

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

    contact = _validate_contact(sec, rigid, constrain, dim)
    if contact.get("contact", "bonded") != "bonded" and geometry["type"] not in CONTACT_GEOMETRIES:
        _fail(sec.sub("contact"), contact["contact"], f"bonded with a {geometry['type']} geometry (a "
              f"contact law needs the tool's surface: {', '.join(CONTACT_GEOMETRIES)})")
    return {"name": name, "material": material, "rigid": rigid, "geometry": geometry,
            "particles_per_cell": ppc, "velocity": velocity, "function": function,
            "constrain": constrain, **contact}


#: the keys of the contact laws' regularization: each one's default and the laws that take it
REGULARIZATION_KEYS = {"slip_tolerance": (DEFAULT_SLIP_TOLERANCE, ("friction",)),
                       "tangential_stiffness": (DEFAULT_TANGENTIAL_STIFFNESS, ("friction", "tied"))}


def _validate_contact(sec, rigid, constrain, dim):
    """A rigid body's contact law (pimpm.contact): ``contact`` (bonded by
    default), ``friction_coefficient`` (friction only) and
    ``contact_stiffness`` (frictionless, friction and tied), ``slip_tolerance``
    (friction only) and ``tangential_stiffness`` (friction and tied)."""
    for key in ("contact", "friction_coefficient", "contact_stiffness") + tuple(REGULARIZATION_KEYS):
        if sec.has(key) and not rigid:
            _fail(sec.sub(key), sec.data[key], f"no '{key}' on a deformable body (a contact law is "
                                               "a rigid body's, with rigid: true)")
    law = sec.optional("contact")
    law = "bonded" if law is _MISSING else _enum(law, sec.sub("contact"), TOOL_LAWS)
    if not rigid:
        return {}
    out = {"contact": law}
    mu = sec.optional("friction_coefficient")
    if law == "friction":
        expected = "a number >= 0 (Coulomb's coefficient of friction)"
        if mu is _MISSING:
            _fail_missing(sec.sub("friction_coefficient"), expected + " with contact: friction")
        mu = _float(mu, sec.sub("friction_coefficient"), expected)
        if mu < 0.0:
            _fail(sec.sub("friction_coefficient"), sec.data["friction_coefficient"], expected)
        out["friction_coefficient"] = mu
    elif mu is not _MISSING:
        _fail(sec.sub("friction_coefficient"), mu, f"no friction_coefficient with contact: {law} "
                                                   "(it applies only with contact: friction)")
    for key, (default, laws) in REGULARIZATION_KEYS.items():
        value = sec.optional(key)
        if law in laws:
            out[key] = default if value is _MISSING else _positive(value, sec.sub(key))
        elif value is not _MISSING:
            _fail(sec.sub(key), sec.data[key], f"no {key} with contact: {law} "
                                               f"(it applies only with contact: {' or '.join(laws)})")
    stiffness = sec.optional("contact_stiffness")
    if law != "bonded":
        out["contact_stiffness"] = DEFAULT_CONTACT_STIFFNESS if stiffness is _MISSING else \
            _positive(stiffness, sec.sub("contact_stiffness"))
        if sec.has("constrain") and list(constrain) != list(AXES[:dim]):
            _fail(sec.sub("constrain"), sec.data["constrain"], f"no 'constrain' with contact: {law} "
                  "(the contact law sets what the tool holds; constrain is bonded contact's)")
    elif stiffness is not _MISSING:
        _fail(sec.sub("contact_stiffness"), stiffness, f"no contact_stiffness with contact: {law} "
                                                       "(it applies to frictionless, friction and tied)")
    return out


def _validate_bodies(value, path, dim, materials, grid, functions=None, base_dir=None):
    """``base_dir``: where relative geometry file paths start (the input
    file's directory; the working directory if None)."""
    if not isinstance(value, (list, tuple)) or not value:
        _fail(path, value, "a non-empty list of bodies")
    bodies, first = [], {}
    for i, spec in enumerate(value):
        bpath = f"{path}[{i}]"
        body = _validate_body(spec, bpath, dim, materials, grid, functions, base_dir)
        if body["name"] in first:
            _fail(f"{bpath}.name", body["name"],
                  f"a unique body name (already used by {path}[{first[body['name']]}])")
        first[body["name"]] = i
        bodies.append(body)
    if all(b["rigid"] for b in bodies):
        _fail(path, [b["name"] for b in bodies],
              "at least one deformable body (rigid: false); all bodies are rigid")
    return bodies
