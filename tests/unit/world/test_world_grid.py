"""The 4x4x4 workspace grid: geometry, nearest cells, reachability."""

import numpy as np

from cbgo.world import DEFAULT_GRID, Grid

PANDA_SHOULDER = np.array([0.0, 0.0, 0.333])
PANDA_REACH = 0.855


def test_the_grid_has_four_cells_along_each_axis_in_front_of_the_robot():
    cells = list(DEFAULT_GRID.cells())
    assert len(cells) == 64 and len(list(DEFAULT_GRID.columns())) == 16
    xs = sorted({DEFAULT_GRID.position(c)[0] for c in cells})
    ys = sorted({DEFAULT_GRID.position(c)[1] for c in cells})
    assert np.allclose(xs, [0.32, 0.44, 0.56, 0.68]) and np.allclose(ys, [-0.18, -0.06, 0.06, 0.18])
    assert all(DEFAULT_GRID.position(c)[2] > 0 for c in cells)


def test_every_cell_is_within_the_reach_of_a_panda_with_margin_for_the_hand():
    for cell in DEFAULT_GRID.cells():
        # a top-down grasp puts the wrist ~0.2 m above the TCP
        wrist = np.array(DEFAULT_GRID.position(cell)) + [0.0, 0.0, 0.2]
        assert np.linalg.norm(wrist - PANDA_SHOULDER) < PANDA_REACH - 0.05, cell


def test_a_position_maps_to_its_nearest_cell_and_clamps_outside_the_grid():
    for cell in DEFAULT_GRID.cells():
        assert DEFAULT_GRID.cell_of(DEFAULT_GRID.position(cell)) == cell
    assert DEFAULT_GRID.cell_of((0.455, -0.05, 0.13)) == (1, 1, 1)
    assert DEFAULT_GRID.cell_of((5.0, -5.0, -1.0)) == (3, 0, 0)
    assert DEFAULT_GRID.column_of((0.69, 0.17, 0.9)) == (3, 3)
    assert not DEFAULT_GRID.contains((4, 0, 0)) and DEFAULT_GRID.contains((3, 3, 3))


def test_columns_by_distance_start_at_the_given_column_and_cover_the_grid():
    order = Grid().columns_by_distance((0, 0))
    assert order[0] == (0, 0) and set(order[1:4]) == {(0, 1), (1, 0), (1, 1)}
    assert len(order) == 16 and len(set(order)) == 16
