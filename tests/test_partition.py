"""pimpm.partition: ownership ranges from the particle distribution."""
import numpy as np
import pytest

from pimpm.partition import balanced_ownership


@pytest.mark.parametrize("parts", [1, 2, 3, 5])
def test_ranges_cover_the_nodes_and_split_the_work_to_one_cell_layer(parts):
    rng = np.random.default_rng(parts)
    weights = np.zeros(80)
    weights[:40] = rng.integers(20, 40, 40)            # particles in the left half only
    (ranges,) = balanced_ownership([weights], [parts], min_nodes=2)
    assert ranges.sum() == 81 and np.all(ranges >= 2)
    cuts = np.concatenate([[0], np.cumsum(ranges)])
    # a rank owns the cells of its nodes (the last node has no cell)
    work = np.array([weights[a:min(b, 80)].sum() for a, b in zip(cuts, cuts[1:])])
    assert np.all(np.abs(work - weights.sum() / parts) <= weights.max())


def test_without_particles_the_cells_are_split_evenly():
    (ranges,) = balanced_ownership([np.zeros(11)], [3])
    cells = ranges - np.r_[0, 0, 1]                    # the last node has no cell
    assert ranges.sum() == 12 and cells.max() - cells.min() <= 1


def test_each_axis_is_split_on_its_own():
    wx, wy = np.r_[np.ones(10), np.zeros(10)], np.ones(6)
    rx, ry = balanced_ownership([wx, wy], [2, 2])
    assert list(rx) == [5, 16] and list(ry) == [3, 4]


def test_min_nodes_wins_over_balance():
    weights = np.zeros(20)
    weights[0] = 100.0                                 # all the work in the first cell
    (ranges,) = balanced_ownership([weights], [4], min_nodes=2)
    assert ranges.sum() == 21 and np.all(ranges >= 2)
