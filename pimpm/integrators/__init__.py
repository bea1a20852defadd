"""Time integrators, one module per scheme, chosen by lookup in
:data:`INTEGRATORS` (``time.integrator``). Adding one is a new module and
one line here.

* :mod:`.quasi_static`: no inertia (G&W 5.1.1);
* :mod:`.newmark`: the trapezoidal rule of Guilkey & Weiss (eq. 14-16);
* :mod:`.backward_euler`: Sulsky & Kaul's theta = 1 scheme;
* :mod:`.explicit`: the explicit MPM step of the MPM introduction (eq. 1-10).

Implicit integrators share the interface of :class:`.base.ImplicitIntegrator`;
the explicit one owns its whole step.
"""
from .backward_euler import BackwardEuler
from .explicit import Explicit
from .newmark import Newmark
from .quasi_static import QuasiStatic

#: ``time.integrator`` name -> (class, {time key: constructor argument})
INTEGRATORS = {
    "newmark": (Newmark, {}),
    "quasi_static": (QuasiStatic, {}),
    "explicit": (Explicit, {}),
    "backward_euler": (BackwardEuler, {}),
}


def make_integrator(time_config):
    cls, arguments = INTEGRATORS[time_config["integrator"]]
    return cls(**{arg: time_config[key] for key, arg in arguments.items()})
