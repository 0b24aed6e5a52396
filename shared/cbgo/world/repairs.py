"""Which unmet preconditions a robot cell's planner repairs with one action on a known object.

One home for knowledge two services share: the planner carries these repairs out
(`cbgo.services.planner.repair`: it opens a closed drawer, it places a held object first), and
intent lets an intent compete when these are all that stand in its way (``accept_repairable``).
The repair itself is the world model's (`Failure.repair`, e.g. ``("open", "drawer1")``).

The planner repairs more (``not_free``, ``not_holding``, ...), but those repairs move or fetch
*other* objects (a tower taken off, a source chosen): they depend on the planner's choices, and
no intent model is trained or measured on such intents, so they are not listed here.
"""

from __future__ import annotations

from collections.abc import Sequence

from cbgo.world.actions import Failure, InfeasibleAction, apply, failures, feasible
from cbgo.world.grid import DEFAULT_GRID, Grid
from cbgo.world.scene import Scene

# failure code -> what the planner does about it (for docs and messages; the action is
# the failure's own `repair`)
ONE_ACTION_REPAIRS: dict[str, str] = {
    "drawer_closed": "open the drawer",
    "holding": "place the held object first",
}
REPAIRABLE = frozenset(ONE_ACTION_REPAIRS)


def only_repairable(found: Sequence[Failure]) -> bool:
    """Returns whether there are unmet preconditions and the planner repairs every one."""
    return bool(found) and all(f.code in REPAIRABLE for f in found)


def after_repairs(action: str, obj: str, scene: Scene,
                  grid: Grid = DEFAULT_GRID) -> Scene | None:
    """Returns the scene once the planner has repaired `action` on `obj`, else None.

    None unless `action` is infeasible, every unmet precondition is one the planner repairs
    (`REPAIRABLE`), each repair applies (`cbgo.world.apply`), and `action` is feasible
    afterwards. Moves and place have no such preconditions.
    """
    found = failures(action, obj, scene, grid=grid)
    if not only_repairable(found) or any(f.repair is None for f in found):
        return None
    repaired = scene
    try:
        for f in found:
            repaired = apply(*f.repair, None, repaired, grid)
    except InfeasibleAction:  # e.g. no free place to set the held object down
        return None
    return repaired if feasible(action, obj, repaired, grid=grid) else None
