"""Validation of the ``loads`` section: forces applied to the particles of
deformable bodies, each scaled by a function of time (the runtime objects
are :mod:`pimpm.loads`)."""
from .checks import _MISSING, _Section, _choices, _enum, _fail, _float_vector, _fmt, _join, _name, _ordered_bounds
from .functions import _function_ref
from .schema import AXES

LOAD_TYPES = ("traction", "point", "body_force")
LOAD_KEYS = {"traction": ("name", "type", "body", "region", "normal", "traction", "function"),
             "point": ("name", "type", "body", "point", "force", "function"),
             "body_force": ("name", "type", "body", "acceleration", "function")}


def normals(dim):
    return [f"{a}{s}" for a in AXES[:dim] for s in ("-", "+")]


def _validate_loads(value, path, dim, bodies, functions, grid):
    if value is _MISSING or value is None:
        return []
    if not isinstance(value, (list, tuple)):
        _fail(path, value, "a list of loads")
    deformable = [b["name"] for b in bodies if not b["rigid"]]
    taken = {b["name"]: "a body" for b in bodies}
    loads = []
    for i, spec in enumerate(value):
        lpath = f"{path}[{i}]"
        if not isinstance(spec, dict) or "type" not in spec:
            _fail(lpath, spec, f"a mapping with key 'type' ({_choices(LOAD_TYPES)})")
        kind = _enum(spec["type"], _join(lpath, "type"), LOAD_TYPES)
        sec = _Section(spec, lpath, LOAD_KEYS[kind])
        name = sec.optional("name")
        name = f"{kind}{i}" if name is _MISSING else _name(name, sec.sub("name"))
        if name in taken:
            _fail(sec.sub("name"), name, f"a name not already used by {taken[name]}")
        taken[name] = f"{path}[{i}]"
        body = sec.required("body", f"the name of a deformable body: {', '.join(deformable)}")
        if body not in deformable:
            _fail(sec.sub("body"), body, f"the name of a deformable body: {', '.join(deformable)}")
        geometry = next(b["geometry"]["type"] for b in bodies if b["name"] == body)
        if kind == "traction" and geometry == "particles":
            _fail(sec.sub("body"), body, "a body with a surface (a particle cloud has no faces "
                                         "to load: use a point or body_force load)")
        load = {"name": name, "type": kind, "body": body,
                "function": _function_ref(sec.optional("function"), sec.sub("function"), functions)}
        if kind == "traction":
            load["traction"] = _float_vector(sec.required("traction", f"a list of {dim} numbers"),
                                             sec.sub("traction"), dim)
            load["normal"] = _enum(sec.required("normal", _choices(normals(dim))), sec.sub("normal"),
                                   normals(dim), " (the outward normal of the loaded faces)")
            region = sec.optional("region")
            if region is _MISSING:
                region = {"lower": list(grid["lower"]), "upper": list(grid["upper"])}
            else:
                rsec = _Section(region, sec.sub("region"), ("lower", "upper"))
                lower, upper = _ordered_bounds(rsec, dim)
                region = {"lower": lower, "upper": upper}
            load["region"] = region
        elif kind == "point":
            load["point"] = _float_vector(sec.required("point", f"a list of {dim} numbers"),
                                          sec.sub("point"), dim)
            load["force"] = _float_vector(sec.required("force", f"a list of {dim} numbers"),
                                          sec.sub("force"), dim)
        else:
            load["acceleration"] = _float_vector(
                sec.required("acceleration", f"a list of {dim} numbers (force per unit mass)"),
                sec.sub("acceleration"), dim)
        loads.append(load)
    return loads
