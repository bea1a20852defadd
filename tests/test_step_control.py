"""Step sizes: the last steps land on end_time without a sliver."""
import pytest

from pimpm.step_control import TimeStepControl


def control(dt, end, dt_initial=None):
    return TimeStepControl({"dt": dt, "dt_initial": dt_initial or dt, "ramp_factor": 1.2,
                            "max_cuts": 4, "easy_newton_iterations": 6, "end_time": end})


def steps(c):
    t, sizes = 0.0, []
    while not c.done(t):
        dt = c.next_dt(t)
        sizes.append(dt)
        t += dt
        c.succeeded(3)
    return t, sizes


@pytest.mark.parametrize("dt,end", [(0.25, 1.0), (0.3, 1.0), (0.33, 1.0), (0.2, 1.05), (0.7, 1.0)])
def test_steps_land_on_the_end_and_none_is_a_sliver(dt, end):
    t, sizes = steps(control(dt, end))
    assert t == pytest.approx(end, rel=1e-12)
    assert max(sizes) <= dt * (1 + 1e-12)
    assert min(sizes) >= 0.25 * min(dt, end)      # no step shorter than a quarter step


def test_whole_steps_are_kept_when_end_time_is_a_multiple():
    _, sizes = steps(control(0.005, 0.2))
    assert len(sizes) == 40 and all(abs(s - 0.005) < 1e-15 for s in sizes)


def test_after_cuts_the_end_is_split_rather_than_slivered():
    c = control(1e-3, 9e-3)
    t = 8.7352e-3                      # the 3D upsetting after its cuts: dt 2.592e-4 left 5.6e-6
    c.dt = 2.592e-4
    first = c.next_dt(t)
    assert first == pytest.approx(0.5 * (9e-3 - t))
    assert c.next_dt(t + first) == pytest.approx(first)


def test_failures_between_tiny_successes_cannot_shrink_the_step_forever():
    """A hopeless run (each step fails, then succeeds when cut): the cuts may
    not take dt below 2^-max_cuts of time.dt, so the run stops within a few
    steps instead of creeping on ever tinier ones."""
    c = control(0.01, 1.0)
    stopped_after = None
    for attempt in range(100):
        if not c.failed():
            stopped_after = attempt
            break
        assert c.dt >= 0.01 / 16 * (1 - 1e-12)
        c.succeeded(20)                # a hard (not easy) success: dt does not grow back
    assert stopped_after is not None and stopped_after <= 4
