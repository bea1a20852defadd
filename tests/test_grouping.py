"""Particles are grouped for assembly by the whole list of nodes they touch."""
import numpy as np

from pimpm.implicit.momentum import group_by_node_set


def groups(node_index):
    order, starts = group_by_node_set(np.asarray(node_index), 100)
    bounds = list(starts) + [len(order)]
    return [sorted(order[a:b].tolist()) for a, b in zip(bounds, bounds[1:])]


def test_rows_with_the_same_first_and_last_node_but_other_lists_are_apart():
    # one cell wide, 3 nodes per axis, clipped at both ends: (0, 0, 1) and (0, 1, 1)
    rows = [[0, 0, 1], [0, 1, 1], [0, 0, 1], [2, 3, 4], [0, 1, 1]]
    found = groups(rows)
    assert sorted(found) == [[0, 2], [1, 4], [3]]
    for group in found:
        assert all(rows[i] == rows[group[0]] for i in group)


def test_without_clipping_the_order_is_a_stable_sort_by_first_and_last_node():
    rng = np.random.default_rng(3)
    base = rng.integers(0, 8, size=200)
    rows = np.stack([base, base + 1, base + 10, base + 11], axis=1)
    order, starts = group_by_node_set(rows, 100)
    key = rows[:, 0] * 100 + rows[:, -1]
    assert np.array_equal(order, np.argsort(key, kind="stable"))
    assert len(starts) == len(np.unique(key))
