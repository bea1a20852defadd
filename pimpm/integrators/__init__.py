"""Time integrators, one module per scheme, chosen by lookup in
:data:`INTEGRATORS` (``time.integrator``). Adding one is a new module and
one line here.

* :mod:`.quasi_static`: no inertia (G&W 5.1.1);
* :mod:`.newmark`: the trapezoidal rule of Guilkey & Weiss (eq. 14-16);
* :mod:`.backward_euler`: Sulsky & Kaul's theta = 1 scheme;
* :mod:`.hht`: Hilber-Hughes-Taylor alpha (controllable high-frequency damping);
* :mod:`.explicit`: the explicit MPM step of the MPM introduction (eq. 1-10).

Implicit integrators share the interface of :class:`.base.ImplicitIntegrator`;
the explicit one owns its whole step.
"""
from .backward_euler import BackwardEuler
from .explicit import Explicit
from .hht import HHT
from .newmark import Newmark
from .quasi_static import QuasiStatic

#: ``time.integrator`` name -> class (the order is the one error messages list)
INTEGRATORS = {cls.name: cls for cls in (Newmark, QuasiStatic, Explicit, BackwardEuler,
                                         HHT)}


def make_integrator(time_config):
    """The integrator named by ``time.integrator``, with the ``time`` keys it
    declares in its ``parameters`` as constructor arguments."""
    cls = INTEGRATORS[time_config["integrator"]]
    return cls(**{key: time_config[key] for key in cls.parameters})
