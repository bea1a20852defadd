"""What a material model is: a declaration (:class:`Model`) of its name, its
parameters, its history fields and its two compiled functions, and a
material (:class:`Material`): a model with the values of one input's
``materials`` entry. Everything else is generated from the declarations:
the model codes the kernels dispatch on (the position in
:data:`pimpm.materials.MODELS`), the packed parameters (``[mu, kappa]`` then
the declared parameters in order, any number of them, then the model's
constants) with their offsets (:func:`parameter_offsets`), and the history
offsets (:func:`history_offsets`).

A model's compiled functions (``@jit`` from :mod:`pimpm.kernels.jit`):

* ``point(prm, F, h_in, h_out, sigma, c, want_c, w, D, in_plane)``: the
  Cauchy stress ``sigma`` (3, 3), the spatial tangent ``c`` (3, 3, 3, 3;
  written only if ``want_c``; with ``in_plane`` it may write only the entries
  whose indices are all 0 or 1) and the history ``h_out`` after the
  deformation gradient ``F``, from the packed parameters ``prm`` and the
  history ``h_in`` committed at t; ``w`` (8, 3, 3) and ``D`` (3, 3, 3, 3)
  are scratch. NaN stress where det F <= 0.
* ``energy(prm, F, h)``: the stored energy per unit reference volume.

Tangent convention. ``c`` is the spatial elasticity tensor
``c_ijkl = J^-1 F_iI F_jJ F_kK F_lL 4 d2W/dC_IJ dC_KL``, i.e. the tangent of
the Truesdell (Lie) rate of the Kirchhoff stress ``tau = J sigma`` divided by J:

    L_v tau = tau_dot - l tau - tau l^T = J c : d,      d = sym(l).

Hence, for ``F_eps = (I + eps H) F``,
``d tau / d eps |_0 = J c : H + H tau + tau H^T``. The spatial tangent
stiffness used by the implicit solver is ``c_ijkl + delta_ik sigma_jl``
(material + geometric part).
"""
from collections import namedtuple

import numpy as np

#: marks a parameter without a default
REQUIRED = object()

#: a model parameter: its default in the input (REQUIRED, or None: the
#: model's own, ``absent``), whether it must be positive (else any finite
#: number), and the packed value when it is not given
Parameter = namedtuple("Parameter", "default positive absent", defaults=(0.0,))

#: yield stress and the bilinear hardening / softening of Sulsky & Kaul eq. 2.1.19
#: (the J2 models' parameters)
PLASTICITY = {"yield_stress": Parameter(REQUIRED, True),
              "hardening_modulus": Parameter(0.0, False),
              "softening_strain": Parameter(None, True, np.inf),
              "softening_modulus": Parameter(0.0, False)}


def parameter_offsets(parameters, constants=()):
    """Each parameter's place in a material's packed parameters: [mu, kappa]
    (0, 1), then the declared parameters, then the constants: name -> offset."""
    return {name: 2 + i for i, name in enumerate(list(parameters) + list(constants))}


def history_offsets(history):
    """Each history field's first column in a particle's packed history
    (fields one after the other in declaration order): name -> offset."""
    offsets, start = {}, 0
    for name, shape in history.items():
        offsets[name] = start
        start += int(np.prod(shape, dtype=int))
    return offsets


class Model:
    """A material model's declaration (module docstring). ``code`` is set
    by the registry (:data:`pimpm.materials.MODELS`)."""

    def __init__(self, name, point, energy, parameters=None, history=None, symmetric_tangent=True,
                 identity_history=(), constants=None, output=()):
        self.name = name
        self.point = point
        self.energy = energy
        #: parameters beyond the elastic constants and the density: name -> Parameter
        self.parameters = dict(parameters or {})
        #: values packed after the parameters that the input does not set: name ->
        #: number (two models sharing a point function share a packing this way)
        self.constants = dict(constants or {})
        #: history carried by each particle: name -> per-particle shape
        self.history = dict(history or {})
        #: history fields written with the particles at every output step
        self.output = tuple(output)
        #: history fields that start at the identity tensor (the others at zero)
        self.identity_history = tuple(identity_history)
        #: is the consistent tangent symmetric? (measured by tests/mpi/jacobian_check.py)
        self.symmetric_tangent = symmetric_tangent
        self.code = None

    @property
    def history_width(self):
        return int(sum(np.prod(shape, dtype=int) for shape in self.history.values()))

    def initial_history(self):
        """name -> (per-particle shape, value at the start of a run)."""
        return {name: (shape, np.eye(3) if name in self.identity_history else 0.0)
                for name, shape in self.history.items()}

    def __repr__(self):
        return f"Model({self.name!r})"


def elastic_moduli(spec):
    """(shear_modulus, bulk_modulus) from a material spec.

    Uses ``shear_modulus`` and ``bulk_modulus`` if both are given, otherwise
    ``youngs_modulus`` E and ``poisson_ratio`` nu:
    mu = E / (2 (1 + nu)),  kappa = E / (3 (1 - 2 nu)).
    """
    if "shear_modulus" in spec and "bulk_modulus" in spec:
        return float(spec["shear_modulus"]), float(spec["bulk_modulus"])
    if "youngs_modulus" in spec and "poisson_ratio" in spec:
        E = float(spec["youngs_modulus"])
        nu = float(spec["poisson_ratio"])
        if not (E > 0 and -1.0 < nu < 0.5):
            raise ValueError(f"need youngs_modulus > 0 and -1 < poisson_ratio < 0.5, got E={E}, nu={nu}")
        return E / (2.0 * (1.0 + nu)), E / (3.0 * (1.0 - 2.0 * nu))
    raise ValueError(
        "material spec needs either shear_modulus and bulk_modulus, "
        "or youngs_modulus and poisson_ratio"
    )


def youngs_modulus(shear_modulus, bulk_modulus):
    """E = 9 kappa mu / (3 kappa + mu)."""
    return 9.0 * bulk_modulus * shear_modulus / (3.0 * bulk_modulus + shear_modulus)


class ElasticConstants:
    """The constants derived from ``shear_modulus``, ``bulk_modulus`` and
    ``density`` (mixed into pimpm's materials and their numpy references)."""

    @property
    def lame_lambda(self):
        """First Lame parameter lambda = kappa - 2/3 mu."""
        return self.bulk_modulus - 2.0 / 3.0 * self.shear_modulus

    @property
    def youngs_modulus(self):
        return youngs_modulus(self.shear_modulus, self.bulk_modulus)

    @property
    def p_wave_modulus(self):
        """kappa + 4/3 mu (uniaxial-strain stiffness)."""
        return self.bulk_modulus + 4.0 / 3.0 * self.shear_modulus

    def wave_speed(self):
        """Small-strain dilatational wave speed sqrt((kappa + 4/3 mu) / rho)."""
        return float(np.sqrt(self.p_wave_modulus / self.density))


class Material(ElasticConstants):
    """A model with its values: the shear and bulk moduli, the density and
    the model's own parameters (``values``: name -> number; a parameter
    not given takes its default, or its packed ``absent`` value)."""

    def __init__(self, model, shear_modulus, bulk_modulus, density, **values):
        self.model = model
        self.shear_modulus = float(shear_modulus)
        self.bulk_modulus = float(bulk_modulus)
        self.density = float(density)
        if not (self.shear_modulus > 0 and self.bulk_modulus > 0 and self.density > 0):
            raise ValueError(f"{model.name}: shear_modulus, bulk_modulus and density must be > 0 "
                             f"(got {shear_modulus}, {bulk_modulus}, {density})")
        unknown = set(values) - set(model.parameters)
        if unknown:
            raise ValueError(f"{model.name} takes no parameter {sorted(unknown)[0]!r}")
        #: F-bar (pimpm.fbar): False, or what the volume change is averaged over ("cells", "nodes")
        self.f_bar = False
        #: ... and the particle's own share in the volume change the material sees:
        #: det F_bar = J_bar^(1 - blend) J^blend
        self.f_bar_blend = 0.0
        self.values = {}
        for key, parameter in model.parameters.items():
            value = values.get(key)
            if value is None:
                if parameter.default is REQUIRED:
                    raise ValueError(f"{model.name} needs {key}")
                value = parameter.absent if parameter.default is None else parameter.default
            self.values[key] = float(value)

    name = property(lambda self: self.model.name)
    history = property(lambda self: self.model.history)
    parameters = property(lambda self: self.model.parameters)
    symmetric_tangent = property(lambda self: self.model.symmetric_tangent)
    code = property(lambda self: self.model.code)

    def __getattr__(self, key):
        values = self.__dict__.get("values", {})
        if key in values:
            return values[key]
        raise AttributeError(key)

    def packed_parameters(self):
        """The parameters as the compiled kernels take them: [mu, kappa, then
        the model's parameters in declaration order, then its constants]
        (:func:`parameter_offsets`)."""
        return np.array([self.shear_modulus, self.bulk_modulus] + list(self.values.values())
                        + list(self.model.constants.values()))

    def __repr__(self):
        values = "".join(f", {k}={v!r}" for k, v in self.values.items())
        return (f"Material({self.name!r}, shear_modulus={self.shear_modulus!r}, "
                f"bulk_modulus={self.bulk_modulus!r}, density={self.density!r}{values})")
