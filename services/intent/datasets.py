"""The paper's synthetic intent datasets D1–D5, generated from its decision tables.

Each observation is drawn as in the paper (section "Artificial datasets generation"):

1. a random valid scene (`cbgo.world.random_scene`);
2. an intent uniform over the scene's feasible (action, object) pairs — moves and place are
   feasible or not regardless of the object, so they pair with every object, which is then the
   object the person looks at; objects hidden in a closed drawer are not looked at (the paper's
   code let them be, with the drawer's position: a focus cannot tell them apart);
3. the user, uniform over ``user1``, ``user2``;
4. the gesture from the dataset's decision table (`cbgo/data/gesture_tables.json`): its context
   is the target object's type and state bit and the user, as far as the dataset has those
   dimensions (D1 none, D2 type, D3 user × type, D4 state × user × type); a draw whose table
   entry is null is discarded and drawn again;
5. the gesture vector g: the gesture's one-hot plus N(0, 0.2) on every entry, absolute value,
   normalised to sum 1;
6. the focus: the target's position plus N(0, σ) per axis, σ = 0.1 grid cell (1.2 cm).

D5 is D4 with the scene's object order shuffled in every observation (the paper reports its
fixed-slot M5 at 97.4 % on D4 and 92.6 % on D5); with the same seed, D5 holds exactly D4's
observations, shuffled.

**Repairable intents** (``repairable=True``; not in the paper): step 2 also draws the
(action, object) pairs that are infeasible only through preconditions the planner repairs
(`cbgo.world.repairs.REPAIRABLE`: a closed drawer it opens, a held object it places
first) and that are feasible once those repairs are applied to the scene
(`cbgo.world.repairs.after_repairs`: a held object with no free place on the table cannot be
set aside).
The intent is uniform over the feasible and the repairable pairs together. Step 4 reads the
table in the target's state after the repairs, the state in which the request is feasible: put
into a closed drawer gets the open drawer's gesture (D4: user1 ``five``, user2 ``point``);
pick up while holding something gets the target's own entry (setting the held object aside
does not change the target). The assumption behind it: a person whose robot runs the planner
asks for the goal with the gesture they use for that goal, not for the repairs. Without
``repairable`` (the default) the draws are the paper's datasets.

File format (``cbgo data intent make``): a NumPy ``.npz`` (no pickles; load with
``allow_pickle=False``), N observations, objects padded to K = 7 slots in scene order:

========================  =========  =======================================================
array                     dtype      meaning
========================  =========  =======================================================
``g``                     f4 (N,G)   gesture vector, columns in ``meta.gestures`` order
``user``                  i1 (N,)    index into ``meta.users``
``focus``                 f4 (N,3)   focus point, m (robot base frame)
``n_objects``             i1 (N,)    objects in the scene (the first n slots are used)
``obj_type``              i1 (N,K)   index into ``meta.object_types``; −1 for empty slots
``obj_state``             i1 (N,K)   state bit (cup full, drawer open, box blocked)
``obj_held``              ?  (N,K)   the robot holds this object
``obj_hidden``            ?  (N,K)   inside a closed drawer (out of sight)
``obj_pos``               f4 (N,K,3) object centre, m
``obj_name``              U  (N,K)   object name ('' for empty slots)
``feasible``              ?  (N,A,K) action × slot feasible in the scene (moves and place:
                                     the same for every object)
``repairable``            ?  (N,A,K) action × slot infeasible, but feasible after the
                                     planner's repairs (`cbgo.world.repairs.after_repairs`)
``repaired``              ?  (N,)    the intent is one of those (only with ``repairable``)
``action``                i1 (N,)    the intended action, index into ``meta.actions``
``target``                i1 (N,)    the intended object's slot
``gesture``               i1 (N,)    the table's gesture, index into ``meta.gestures``
``meta``                  U  ()      JSON: dataset, seed, n, repairable, the vocabularies,
                                     noise, σ
========================  =========  =======================================================
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from cbgo.errors import ConfigError
from cbgo.wire import ACTIONS, OBJECT_TYPES
from cbgo.world import DEFAULT_GRID, OBJECT_AGNOSTIC, Grid, Scene, feasible, random_scene
from cbgo.world.repairs import after_repairs

DATASETS = ("D1", "D2", "D3", "D4", "D5")
MAX_OBJECTS = 7
GESTURE_NOISE = 0.2
FOCUS_SIGMA_CELLS = 0.1
FORMAT = "cbgo-intent-dataset/1"


@dataclass(frozen=True)
class Tables:
    """The decision tables of gesture_tables.json.

    Attributes:
        gestures: the gesture vocabulary (the columns of g).
        users: the simulated users.
        tables: dataset name (D1-D4) -> its nested table.
        sha256: digest of the file, for provenance.
    """

    gestures: tuple[str, ...]
    users: tuple[str, ...]
    tables: dict[str, Any]
    sha256: str

    def gesture(self, dataset: str, action: str, obj_type: str, state: int,
                user: str) -> str | None:
        """Returns the gesture a simulated user makes for an intent in a context, or None."""
        table = self.tables["D4" if dataset == "D5" else dataset]
        if dataset == "D1":
            return table[action]
        if dataset == "D2":
            return table[obj_type][action]
        if dataset == "D3":
            return table[user][obj_type][action]
        return table[str(state)][user][obj_type][action]


@functools.lru_cache(maxsize=1)
def load_tables() -> Tables:
    """Returns the vendored decision tables (``cbgo/data/gesture_tables.json``)."""
    raw = resources.files("cbgo.data").joinpath("gesture_tables.json").read_bytes()
    data = json.loads(raw)
    if tuple(data["actions"]) != tuple(sorted(ACTIONS, key=data["actions"].index)) or set(
            data["actions"]) != set(ACTIONS):
        raise ConfigError("gesture_tables.json names other actions than cbgo.wire.ACTIONS")
    return Tables(tuple(data["gestures"]), tuple(data["users"]),
                  {k: v["table"] for k, v in data["datasets"].items()},
                  hashlib.sha256(raw).hexdigest())


@dataclass
class Sample:
    """One observation with its ground truth.

    Attributes:
        scene: the world (objects in the order the model sees them).
        user: the user's name.
        g: the gesture vector, in `Tables.gestures` order.
        focus: the focus point (m).
        action: the intended action.
        target: the intended (or, for moves and place, looked-at) object's name.
        gesture: the gesture the table gave.
        repaired: the intent is infeasible in `scene` and needs the planner's repairs.
    """

    scene: Scene
    user: str
    g: np.ndarray
    focus: np.ndarray
    action: str
    target: str
    gesture: str
    repaired: bool = False


def check_name(name: str) -> str:
    """Returns a dataset name, or raises ConfigError listing the valid ones."""
    if name not in DATASETS:
        raise ConfigError(f"unknown dataset {name!r}; choose one of {', '.join(DATASETS)}")
    return name


def intent_pairs(scene: Scene, grid: Grid = DEFAULT_GRID,
                 repairable: bool = False) -> list[tuple[str, str]]:
    """Returns the (action, object) pairs a dataset draws from: the feasible ones.

    Moves and place pair with every object when they are feasible at all; objects hidden in a
    closed drawer are never targets (a focus cannot tell them from their drawer). With
    `repairable`, the pairs the planner makes feasible (`after_repairs`) are added.
    """
    visible = [name for name in scene.names if not scene.is_hidden(name)]
    out = []
    for action in ACTIONS:
        if action in OBJECT_AGNOSTIC:
            if feasible(action, None, scene, grid=grid):
                out += [(action, name) for name in visible]
            continue
        for name in visible:
            if feasible(action, name, scene, grid=grid) or (
                    repairable and after_repairs(action, name, scene, grid) is not None):
                out.append((action, name))
    return out


def gesture_context(action: str, target: str, scene: Scene,
                    grid: Grid = DEFAULT_GRID) -> tuple[int, bool]:
    """Returns the target's state bit in which `action` is feasible, and whether it needs repairs.

    The state after the planner's repairs when the action is repairable (a closed drawer counts
    as open), else the target's state in `scene`.
    """
    repaired = None if action in OBJECT_AGNOSTIC else after_repairs(action, target, scene, grid)
    return (repaired or scene).state_bit(target), repaired is not None


def gesture_vector(gesture: str, gestures: Sequence[str], rng: np.random.Generator,
                   noise: float = GESTURE_NOISE) -> np.ndarray:
    """Returns one-hot(gesture) + N(0, noise), absolute, normalised to sum 1."""
    g = np.zeros(len(gestures))
    g[gestures.index(gesture)] = 1.0
    g = np.abs(g + rng.normal(0.0, noise, len(gestures)))
    return g / g.sum()


def draw(name: str, rng: np.random.Generator, tables: Tables | None = None,
         users: Sequence[str] | None = None, grid: Grid = DEFAULT_GRID,
         focus_sigma_cells: float = FOCUS_SIGMA_CELLS,
         shuffle_rng: np.random.Generator | None = None,
         repairable: bool = False,
         only: Callable[[str, str, int, str], bool] | None = None) -> Sample | None:
    """Draws one observation of dataset `name`; None when the draw is discarded.

    Args:
        name: D1-D5.
        rng: the random generator (advanced).
        tables: the decision tables (the vendored ones by default).
        users: the users to draw from (all the tables' users by default).
        grid: the workspace grid.
        focus_sigma_cells: focus noise per axis, in grid cells.
        shuffle_rng: D5's object-order shuffles (default: `rng`); a separate generator keeps
            D5 the very observations of D4 with the same seed, shuffled.
        repairable: also draw intents the planner makes feasible (see the module docstring).
        only: keep only the intents for which ``only(action, object type, state bit, gesture)``
            holds (the draw is discarded when none is left); e.g. the contexts a user's
            mapping states, to show a model many of them.
    """
    tables = tables or load_tables()
    users = list(users or tables.users)
    scene = random_scene(rng, grid)
    user = users[rng.integers(len(users))]
    pairs = intent_pairs(scene, grid, repairable)
    if only is not None:
        pairs = [(a, t) for a, t in pairs if _wanted(only, tables, name, a, t, scene, user, grid)]
    if not pairs:
        return None
    action, target = pairs[rng.integers(len(pairs))]
    obj = scene.get(target)
    state, repaired = gesture_context(action, target, scene, grid)
    gesture = tables.gesture(name, action, obj.type, state, user)
    if gesture is None:
        return None
    focus = np.asarray(obj.position) + rng.normal(0.0, focus_sigma_cells * grid.cell_size, 3)
    g = gesture_vector(gesture, tables.gestures, rng)
    if name == "D5":
        order = (shuffle_rng or rng).permutation(len(scene.objects))
        scene.objects = [scene.objects[i] for i in order]
    return Sample(scene, user, g, focus, action, target, gesture, repaired)


def _wanted(only: Callable[[str, str, int, str], bool], tables: Tables, name: str, action: str,
            target: str, scene: Scene, user: str, grid: Grid) -> bool:
    obj_type = scene.get(target).type
    state = gesture_context(action, target, scene, grid)[0]
    gesture = tables.gesture(name, action, obj_type, state, user)
    return gesture is not None and only(action, obj_type, state, gesture)


def samples(name: str, n: int, seed: int, **kwargs: Any) -> Iterator[Sample]:
    """Yields n observations of dataset `name` (discarded draws are drawn again).

    Args:
        name: D1-D5.
        n: how many.
        seed: the random seed (the same seed gives the same observations).
        **kwargs: passed to `draw` (tables, users, grid, focus_sigma_cells, repairable).
    """
    check_name(name)
    rng = np.random.default_rng(seed)
    shuffle_rng = np.random.default_rng([seed, 5])
    made = 0
    while made < n:
        sample = draw(name, rng, shuffle_rng=shuffle_rng, **kwargs)
        if sample is not None:
            made += 1
            yield sample


# ==================================================================== arrays and files


@dataclass
class Dataset:
    """Observations as arrays (see the module docstring for every field)."""

    arrays: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.arrays["action"])

    def __getattr__(self, name: str) -> np.ndarray:
        arrays = self.__dict__.get("arrays", {})
        if name in arrays:
            return arrays[name]
        raise AttributeError(name)

    def subset(self, index: np.ndarray | slice) -> Dataset:
        """Returns the observations at `index` (same metadata)."""
        return Dataset({k: v[index] for k, v in self.arrays.items()}, dict(self.meta))

    def save(self, path: str | Path) -> Path:
        """Writes the dataset as a compressed ``.npz``; returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **self.arrays, meta=np.array(json.dumps(self.meta)))
        return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")

    @classmethod
    def load(cls, path: str | Path) -> Dataset:
        """Reads a dataset written by `save`.

        Raises:
            ConfigError: unreadable file, or not a cbgo intent dataset.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files if k != "meta"}
                meta = json.loads(str(data["meta"]))
        except (OSError, ValueError, KeyError) as e:
            raise ConfigError(f"cannot read dataset {path}: {e}") from None
        if meta.get("format") != FORMAT:
            raise ConfigError(f"{path} is not a {FORMAT} file (format {meta.get('format')!r})")
        return cls(arrays, meta)


def scene_arrays(scene: Scene, k: int, grid: Grid = DEFAULT_GRID) -> dict[str, np.ndarray]:
    """Returns one scene's per-object arrays padded to k slots (obj_*, feasible, n_objects).

    Raises:
        ValueError: the scene has more than k objects.
    """
    if len(scene.objects) > k:
        raise ValueError(f"the scene has {len(scene.objects)} objects; at most {k} fit")
    out = {"obj_type": np.full(k, -1, np.int8), "obj_state": np.zeros(k, np.int8),
           "obj_held": np.zeros(k, bool), "obj_hidden": np.zeros(k, bool),
           "obj_pos": np.zeros((k, 3), np.float32),
           "obj_name": np.full(k, "", dtype="<U32"),
           "feasible": np.zeros((len(ACTIONS), k), bool),
           "repairable": np.zeros((len(ACTIONS), k), bool),
           "n_objects": np.int8(len(scene.objects))}
    for slot, obj in enumerate(scene.objects):
        out["obj_type"][slot] = OBJECT_TYPES.index(obj.type)
        out["obj_state"][slot] = scene.state_bit(obj.name)
        out["obj_held"][slot] = scene.is_held(obj.name)
        out["obj_hidden"][slot] = scene.is_hidden(obj.name)
        out["obj_pos"][slot] = obj.position
        out["obj_name"][slot] = obj.name
    n = len(scene.objects)
    for a, action in enumerate(ACTIONS):
        if action in OBJECT_AGNOSTIC:
            out["feasible"][a, :n] = feasible(action, None, scene, grid=grid)
            continue
        for slot, obj in enumerate(scene.objects):
            out["feasible"][a, slot] = feasible(action, obj.name, scene, grid=grid)
            out["repairable"][a, slot] = not out["feasible"][a, slot] and after_repairs(
                action, obj.name, scene, grid) is not None
    return out


def to_dataset(items: Sequence[Sample], meta: dict[str, Any] | None = None,
               tables: Tables | None = None, k: int = MAX_OBJECTS,
               grid: Grid = DEFAULT_GRID) -> Dataset:
    """Turns samples into a `Dataset` (objects padded to k slots)."""
    tables = tables or load_tables()
    per_scene = [scene_arrays(s.scene, k, grid) for s in items]
    arrays = {key: np.stack([p[key] for p in per_scene]) for key in per_scene[0]} if items \
        else {}
    arrays.update(
        g=np.array([s.g for s in items], np.float32).reshape(len(items), len(tables.gestures)),
        user=np.array([tables.users.index(s.user) for s in items], np.int8),
        focus=np.array([s.focus for s in items], np.float32).reshape(len(items), 3),
        action=np.array([ACTIONS.index(s.action) for s in items], np.int8),
        target=np.array([s.scene.names.index(s.target) for s in items], np.int8),
        gesture=np.array([tables.gestures.index(s.gesture) for s in items], np.int8),
        repaired=np.array([s.repaired for s in items], bool),
    )
    base = {"format": FORMAT, "gestures": list(tables.gestures), "users": list(tables.users),
            "actions": list(ACTIONS), "object_types": list(OBJECT_TYPES), "max_objects": k,
            "gesture_noise": GESTURE_NOISE, "focus_sigma_m": FOCUS_SIGMA_CELLS * grid.cell_size,
            "cell_size_m": grid.cell_size, "tables_sha256": tables.sha256}
    return Dataset(arrays, {**base, **(meta or {})})


def make(name: str, n: int, seed: int = 0, progress: bool = False, repairable: bool = False,
         **kwargs: Any) -> Dataset:
    """Generates dataset `name` with n observations from `seed`.

    Args:
        name: D1-D5.
        n: number of observations.
        seed: random seed.
        progress: show a tqdm bar.
        repairable: also draw intents the planner makes feasible (see the module docstring).
        **kwargs: passed to `draw` (users, grid, focus_sigma_cells).
    """
    from tqdm import tqdm

    items = list(tqdm(samples(name, n, seed, repairable=repairable, **kwargs), total=n,
                      desc=f"generating {name}", disable=not progress, leave=False))
    return to_dataset(items, {"dataset": check_name(name), "seed": seed, "n": n,
                              "shuffled_objects": name == "D5", "repairable": repairable})
