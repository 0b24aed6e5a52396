"""The 4×4×4 grid in front of the robot: where objects stand and where the TCP can go.

The paper places objects on a 4×4×4 grid in front of the robot, every cell of which the arm can
reach, and moves the gripper one cell per ``move_*`` action. Here the grid lives in the robot
base frame (metres, +z up, table top at z = 0), the person standing across the table at +x,
facing the robot (so "left" as the person sees it is −y):

- columns ``(i, j)``: x = 0.32 + 0.12·i (0.32 … 0.68 m, i = 0 nearest the robot),
  y = −0.18 + 0.12·j (−0.18 … 0.18 m, j = 0 on the person's left);
- levels ``k``: TCP heights z = 0.06 + 0.10·k (0.06 … 0.36 m above the table).

Why these numbers: a Franka Panda reaches 0.855 m from its shoulder (0.333 m above the base);
the farthest cell, (0.68, ±0.18, 0.36), is 0.70 m from the base axis horizontally and leaves
margin for a top-down grasp, and the nearest, (0.32, 0, 0.06), is clear of the base. A cell of
0.12 m holds one object footprint (the largest, a drawer cabinet, is 0.11 m).

Objects stand on the table at a column, on top of another object, inside a drawer or in the
gripper; their heights follow from what they stand on (`cbgo.world.scene`). Levels index the
TCP only.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

Cell = tuple[int, int, int]
Column = tuple[int, int]


@dataclass(frozen=True)
class Grid:
    """A regular grid of TCP positions and object columns in the robot base frame.

    Attributes:
        shape: cells along x, y and z.
        origin: the centre of cell (0, 0, 0), metres.
        step: cell size along x, y and z, metres.
    """

    shape: tuple[int, int, int] = (4, 4, 4)
    origin: tuple[float, float, float] = (0.32, -0.18, 0.06)
    step: tuple[float, float, float] = (0.12, 0.12, 0.10)

    @property
    def cell_size(self) -> float:
        """The horizontal cell size (m): the unit of the paper's "grid cell" distances."""
        return float(np.mean(self.step[:2]))

    def contains(self, cell: Sequence[int]) -> bool:
        """Returns whether a cell index lies inside the grid."""
        return all(0 <= int(c) < n for c, n in zip(cell, self.shape, strict=True))

    def position(self, cell: Sequence[int]) -> tuple[float, float, float]:
        """Returns the centre of a cell (m); cells outside the grid extrapolate."""
        return tuple(float(o + s * c) for o, s, c in zip(self.origin, self.step, cell,
                                                         strict=True))

    def column_xy(self, column: Column) -> tuple[float, float]:
        """Returns the (x, y) of a column's centre (m)."""
        x, y, _ = self.position((*column, 0))
        return x, y

    def cell_of(self, position: Sequence[float]) -> Cell:
        """Returns the nearest cell to a position, clamped into the grid."""
        out = []
        for p, o, s, n in zip(position, self.origin, self.step, self.shape, strict=True):
            out.append(int(min(n - 1, max(0, round((float(p) - o) / s)))))
        return out[0], out[1], out[2]

    def column_of(self, position: Sequence[float]) -> Column:
        """Returns the nearest column to a position's (x, y), clamped into the grid."""
        i, j, _ = self.cell_of((position[0], position[1], self.origin[2]))
        return i, j

    def cells(self) -> Iterator[Cell]:
        """Yields every cell, x fastest last (i, j, k in nested order)."""
        for i in range(self.shape[0]):
            for j in range(self.shape[1]):
                for k in range(self.shape[2]):
                    yield i, j, k

    def columns(self) -> Iterator[Column]:
        """Yields every column (i, j)."""
        for i in range(self.shape[0]):
            for j in range(self.shape[1]):
                yield i, j

    def columns_by_distance(self, start: Column) -> list[Column]:
        """Returns every column ordered by grid distance from `start` (ties: i, then j)."""
        return sorted(self.columns(), key=lambda c: (max(abs(c[0] - start[0]),
                                                         abs(c[1] - start[1])),
                                                     abs(c[0] - start[0]) + abs(c[1] - start[1]),
                                                     c))


DEFAULT_GRID = Grid()
