"""Checks of quantities derived from several keys at once, after every
section is valid on its own: moduli whose wave speed, explicit step or
residual scale is not a normal finite number (1e308 overflows, 1e-300
underflows), and runs that would take more steps than anyone can wait for.
Each failure names the key whose value to change."""
import math

from .checks import _fail, _fmt

#: the most time steps a run may take (the step count of time.dt and time.end_time;
#: for explicit runs, of the CFL step at the start)
MAX_STEPS = 10_000_000


def _normal(x):
    """A finite number far from the ends of the double range."""
    return math.isfinite(x) and 1e-250 < abs(x) < 1e250


def check_derived(config):
    dim = config["dim"]
    grid = config["grid"]
    h = min((u - lo) / n for lo, u, n in zip(grid["lower"], grid["upper"], grid["cells"]))
    speeds = []
    for name, m in config["materials"].items():
        mu, kappa, rho = m["shear_modulus"], m["bulk_modulus"], m["density"]
        key = "youngs_modulus" if "youngs_modulus" in m else "bulk_modulus"
        modulus = m.get(key)
        with _no_float_errors():
            young = 9.0 * kappa * mu / (3.0 * kappa + mu)
            p_wave = kappa + 4.0 / 3.0 * mu
            speed = math.sqrt(p_wave / rho) if p_wave / rho >= 0 else math.nan
            scale = young * h ** (dim - 1)
        for what, value in (("Young's modulus", young), ("the p-wave modulus K + 4/3 G", p_wave),
                            ("the wave speed sqrt((K + 4/3 G) / rho)", speed)):
            if not _normal(value):
                _fail(f"materials.{name}.{key}", modulus,
                      f"moduli and a density for which {what} is a finite, normal number "
                      f"(it is {value!r})")
        if not _normal(scale) and _normal(young):
            # the modulus is fine: the grid spacing is what over- or underflows (issue 32:
            # this was blamed on youngs_modulus)
            _fail("grid.upper", grid["upper"],
                  f"a grid whose cell size h = {h:.6g} gives a finite, normal residual scale "
                  f"E h^(dim-1) with materials.{name} (E = {young:.6g}: it is {scale!r}); check the units "
                  f"of grid.lower, grid.upper and grid.cells")
        speeds.append(speed)
    time = config["time"]
    dt = time["dt"]
    if dt is None:                        # explicit, automatic: the CFL step at rest
        dt_step = time["cfl"] * h / max(speeds)
        what = f"the explicit CFL step ({dt_step:.3g})"
    else:
        dt_step = dt
        what = f"time.dt = {_fmt(dt)}"
        if not _normal(dt):
            _fail("time.dt", dt, "a step that is a normal number (between 1e-250 and 1e250)")
    with _no_float_errors():
        steps = time["end_time"] / dt_step
    start = time.get("dt_initial")
    if dt is not None and start is not None and start < dt:
        # the step starts at dt_initial and grows by ramp_factor a step up to dt; a factor of 1
        # never grows it (issue 32: 1e-200 with a factor of 1 ran forever)
        with _no_float_errors():
            if time["ramp_factor"] == 1.0:
                steps, what = time["end_time"] / start, f"time.dt_initial = {_fmt(start)} (time.ramp_factor 1)"
            else:
                steps += math.log(dt / start) / math.log(time["ramp_factor"])
    if not math.isfinite(steps) or steps > MAX_STEPS:
        _fail("time.end_time", time["end_time"], f"at most {MAX_STEPS:,} steps of {what}; "
                                                 f"that makes {steps:.3g}")


class _no_float_errors:
    """Python floats raise OverflowError on x**y and math.sqrt; turn them into inf."""

    def __enter__(self):
        return self

    def __exit__(self, kind, value, traceback):
        return kind in (OverflowError, ZeroDivisionError, ValueError)
