"""The exceptions that end a step or a run without a traceback."""


class SetupError(Exception):
    """The problem cannot be set up as given (bad solver option value, a body
    that gets no particles): reported like bad input, before any output."""


class StepFailed(Exception):
    """A step could not be completed (Newton diverged, a particle inverted or
    left the grid). The state of the simulation is the last good step."""


class OutputFailed(Exception):
    """Writing the results failed (a full disk, a vanished directory): raised
    on every rank at once (the writers agree on it), the run ends with status
    1 and the files as they were after the last good write."""


class UsageError(Exception):
    """Bad use (existing output directory, ...): exit status 2, nothing written."""


#: why a step failed when a plane-stress particle found no thickness with sigma_33 = 0
#: (pimpm.kernels.material_point.solve_thickness)
THICKNESS_FAILURE = ("the plane-stress thickness stretch of a particle did not converge "
                     "(no sigma_33 = 0 within 50 local Newton iterations)")
