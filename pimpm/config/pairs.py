"""Validation of the top-level ``contact`` list: pairs of deformable bodies
that meet with a contact law instead of sharing one grid velocity field
(the runtime objects are :mod:`pimpm.fields`)."""
from .checks import _MISSING, ConfigError, _Section, _enum, _fail, _fail_missing, _float, _fmt
from .schema import CONTACT_LAWS

PAIR_KEYS = ("bodies", "law", "friction_coefficient")


def _validate_contact_pairs(value, path, bodies):
    """[{"bodies": [A, B], "law": ..., "friction_coefficient": mu (friction only)}]."""
    if value is _MISSING or value is None:
        return []
    if not isinstance(value, (list, tuple)):
        _fail(path, value, "a list of contact pairs, e.g. [{bodies: [block, floor], law: friction, "
                           "friction_coefficient: 0.5}]")
    deformable = [b["name"] for b in bodies if not b["rigid"]]
    names = ", ".join(repr(n) for n in deformable)
    seen = {}
    pairs = []
    for i, spec in enumerate(value):
        ppath = f"{path}[{i}]"
        sec = _Section(spec, ppath, PAIR_KEYS)
        expected = f"a list of two different deformable bodies among {names}"
        pair = sec.required("bodies", expected)
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            _fail(sec.sub("bodies"), pair, expected)
        for k, name in enumerate(pair):
            if name not in deformable:
                rigid = " (a rigid body meets the material through its own 'contact' key)" \
                    if any(b["name"] == name for b in bodies) else ""
                _fail(f"{sec.sub('bodies')}[{k}]", name, f"the name of a deformable body among {names}{rigid}")
        if pair[0] == pair[1]:
            _fail(sec.sub("bodies"), pair, expected)
        key = frozenset(pair)
        if key in seen:
            _fail(sec.sub("bodies"), pair, f"a pair not already declared in {seen[key]}")
        seen[key] = ppath
        law = _enum(sec.required("law", "one of bonded, frictionless, friction"), sec.sub("law"), CONTACT_LAWS)
        out = {"bodies": [str(pair[0]), str(pair[1])], "law": law}
        mu = sec.optional("friction_coefficient")
        expected_mu = "a number >= 0 (Coulomb's coefficient of friction)"
        if law == "friction":
            if mu is _MISSING:
                _fail_missing(sec.sub("friction_coefficient"), expected_mu + " with law: friction")
            x = _float(mu, sec.sub("friction_coefficient"), expected_mu)
            if x < 0.0:
                _fail(sec.sub("friction_coefficient"), mu, expected_mu)
            out["friction_coefficient"] = x
        elif sec.has("friction_coefficient"):
            _fail(sec.sub("friction_coefficient"), sec.data["friction_coefficient"],
                  f"no friction_coefficient with law: {law} (it applies only with law: friction)")
        pairs.append(out)
    return pairs


def check_contact_pairs(config):
    """What the multi-field contact of this version runs with: every law in
    every integrator (the implicit ones in the velocity formulation); no
    F-bar; rigid bodies that are bonded (a frictionless or frictional tool
    meets each field through its own law: not yet)."""
    if not config["contact"]:
        return
    if config["time"]["integrator"] != "explicit" and config["time"]["formulation"] != "velocity":
        raise ConfigError(f"contact = {_fmt(config['contact'])}: expected time.formulation: velocity with "
                          f"contact pairs (time.formulation = {config['time']['formulation']!r}: the pairs' "
                          "contact couples two fields' unknowns, which the momentum formulation's "
                          "matrix does not hold)", path="contact")
    for name, material in config["materials"].items():
        if material.get("f_bar"):
            raise ConfigError(f"materials.{name}.f_bar = {material['f_bar']}: expected false in a run with contact pairs "
                              "(F-bar's cell averages would mix the bodies that meet in a cell)",
                              path=f"materials.{name}.f_bar")
    for i, body in enumerate(config["bodies"]):
        if body.get("contact", "bonded") != "bonded":
            raise ConfigError(f"bodies[{i}].contact = {body['contact']!r}: expected bonded in a run with "
                              "contact pairs (a frictionless or frictional tool and several velocity "
                              "fields do not run together in this version)", path=f"bodies[{i}].contact")
