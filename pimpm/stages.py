"""PETSc log stages of a step (shown by ``-log_view``)."""

STAGE_NAMES = ("P2G", "Solve", "Constitutive update", "Assembly", "G2P", "Migration", "Output")
_STAGES = {}


def log_stages():
    """The stages by name, created once per process."""
    if not _STAGES:
        from petsc4py import PETSc
        for name in STAGE_NAMES:
            _STAGES[name] = PETSc.Log.Stage(name)
    return _STAGES


class log_stage:
    """``with log_stage(stage):`` push/pop a PETSc log stage (None: no-op)."""

    def __init__(self, stage):
        self.stage = stage

    def __enter__(self):
        if self.stage is not None:
            self.stage.push()

    def __exit__(self, *exc):
        if self.stage is not None:
            self.stage.pop()
        return False
