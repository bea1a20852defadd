"""Step sizes of a run: the ramp, cuts of failed steps, growth after easy
steps, landing on the end time."""


class TimeStepControl:
    """Step sizes: an optional ramp from ``dt_initial`` up to ``dt`` by at most
    ``ramp_factor`` per step (Sulsky & Kaul 3.1.1 use 20%); a failed step is
    cut in half and retried, at most ``max_cuts`` times in a row and never
    below 2^-max_cuts of the smaller of ``dt`` and ``dt_initial``, so that a
    hopeless run stops instead of creeping on ever tinier steps that succeed
    between failures; after a cut, dt grows back by ``ramp_factor`` after
    each easy step (at most ``easy_newton_iterations`` Newton iterations).
    The last step is shortened to land on ``end_time``."""

    def __init__(self, time_config):
        self.fixed = time_config["dt"]
        self.target = time_config["dt"]
        self.dt = time_config["dt_initial"]
        self.ramp = time_config["ramp_factor"]
        self.max_cuts = time_config["max_cuts"]
        self.easy = time_config["easy_newton_iterations"]
        self.end = time_config["end_time"]
        self.cuts = 0               # consecutive cuts of the current step
        self.initial = self.dt

    def state(self):
        """What a checkpoint keeps: the current step size, the ramp's target
        and start, and the cuts of the step in progress (JSON-able)."""
        return {"dt": self.dt, "target": self.target, "initial": self.initial, "cuts": self.cuts}

    def restore(self, state):
        """Continue from a checkpoint; a time.dt changed since is the new target."""
        self.dt = state["dt"]
        self.initial = state["initial"]
        self.cuts = state["cuts"]
        if self.fixed is None or self.fixed == state["target"]:
            self.target = state["target"]
        elif self.dt is not None:
            self.dt = min(self.dt, self.fixed)

    def set_explicit_step(self, sim):
        """Explicit steps follow the CFL limit (or the fixed time.dt below it)."""
        stable = sim.stable_time_step()
        self.target = stable if self.fixed is None else min(self.fixed, stable / sim.config["time"]["cfl"])
        if self.cuts == 0:
            self.dt = self.target

    def done(self, time):
        return time >= self.end * (1.0 - 1e-12)

    def next_dt(self, time):
        """The next step: dt, or what is left when that is less; when less
        than half a step would be left after this one, the rest is split in
        two equal steps instead, so the run never ends on a sliver (a step
        of 5.6e-6 s after ones of 2.6e-4 s, whose reaction then differs from
        the last full step's by the remap of the grid, not by the load)."""
        remaining = self.end - time
        dt = self.dt
        if dt >= remaining * (1.0 - 1e-9):
            return remaining                  # land on end_time exactly
        if remaining < 1.5 * dt:
            return 0.5 * remaining
        return dt

    def failed(self):
        """Cut the step; False when no cut is left (``max_cuts`` in a row, or
        the step would fall below the floor)."""
        if self.cuts >= self.max_cuts:
            return False
        smallest = min(x for x in (self.initial, self.target) if x is not None)
        if 0.5 * self.dt < smallest * 0.5 ** self.max_cuts * (1.0 - 1e-12):
            return False
        self.cuts += 1
        self.dt *= 0.5
        return True

    def succeeded(self, newton_iterations):
        cuts, self.cuts = self.cuts, 0
        if newton_iterations <= self.easy and self.dt < self.target:
            self.dt = min(self.target, self.dt * self.ramp)
        return cuts
