"""Draw what one moment of a JSON recording's ``foxglove/scene`` holds, with matplotlib.

This is not Foxglove: the Foxglove app cannot run here, so the picture in the README is this
script's rendering of the very entities Foxglove's 3D panel would draw (spheres, lines, cubes,
cylinders, labels, in the robot base frame), and it says so in its title. It replays the
SceneUpdates of a file up to the chosen moment (each entity replaced by its newer version, as
the 3D panel does) and draws the latest version of every entity.

    cbgo export out/demo-.../session.mcap -o foxglove.mcap
    cbgo plot foxglove-scene foxglove.mcap docs/foxglove-scene.png [--at SECONDS]

Without ``--at`` the moment is the last one at which hands, objects and a target were all in
view (else the last with hands).
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

SCENE = "foxglove/scene"


def scene_states(path: Path):
    """Yields (log time s, {entity id: entity}) after each SceneUpdate of the file."""
    entities: dict[str, dict] = {}
    with open(path, "rb") as f:
        for _schema, _channel, message in make_reader(f).iter_messages(topics=[SCENE]):
            update = json.loads(message.data)
            for deletion in update["deletions"]:
                entities.pop(deletion["id"], None)
            entities.update({e["id"]: e for e in update["entities"]})
            yield message.log_time / 1e9, dict(entities)


def _score(entities: dict) -> int:
    hands = bool(entities.get("hands", {}).get("spheres"))
    target = any(m["key"] == "target" and m["value"] for m in
                 entities.get("objects", {}).get("metadata", []))
    return 2 * hands + target + ("objects" in entities)


def pick(path: Path, at: float | None) -> tuple[float, dict]:
    """Returns (s after the first scene, entities) of the moment to draw: `at`, else the best."""
    states = list(scene_states(path))
    if not states:
        raise SystemExit(f"{path} has no {SCENE} channel: export it with `cbgo export` first")
    if at is not None:
        start = states[0][0]
        t, entities = next(((t, e) for t, e in states if t - start >= at), states[-1])
        return t - start, entities
    best = max(_score(e) for _t, e in states)
    t, entities = [(t, e) for t, e in states if _score(e) == best][-1]
    return t - states[0][0], entities


def _rgba(c: dict) -> tuple:
    return (c["r"], c["g"], c["b"], min(1.0, c["a"]))


def _xyz(p: dict) -> tuple:
    return p["x"], p["y"], p["z"]


def _box(ax, centre, size, colour) -> None:
    (x, y, z), (dx, dy, dz) = centre, size
    corners = list(itertools.product((x - dx / 2, x + dx / 2), (y - dy / 2, y + dy / 2),
                                     (z - dz / 2, z + dz / 2)))
    for a, b in itertools.combinations(corners, 2):
        if sum(u != v for u, v in zip(a, b, strict=True)) == 1:  # an edge: one axis differs
            ax.plot(*zip(a, b, strict=True), color=colour, linewidth=1.2)


def _cylinder(ax, centre, size, colour) -> None:
    import numpy as np

    (x, y, z), (dx, _dy, dz) = centre, size
    theta = np.linspace(0, 2 * np.pi, 40)
    for h in (z - dz / 2, z + dz / 2):
        ax.plot(x + dx / 2 * np.cos(theta), y + dx / 2 * np.sin(theta), h, color=colour)
    for t in theta[::8]:
        ax.plot([x + dx / 2 * np.cos(t)] * 2, [y + dx / 2 * np.sin(t)] * 2,
                [z - dz / 2, z + dz / 2], color=colour, linewidth=0.8)


def draw(entities: dict, ax) -> None:
    """Draws every primitive of the entities (spheres as dots scaled by their size)."""
    for entity in entities.values():
        for line in entity["lines"]:
            points = [_xyz(p) for p in line["points"]]
            for a, b in zip(points[::2], points[1::2], strict=False):
                ax.plot(*zip(a, b, strict=True), color=_rgba(line["color"]), linewidth=2.0)
        for s in entity["spheres"]:
            ax.scatter(*_xyz(s["pose"]["position"]), color=_rgba(s["color"]),
                       s=s["size"]["x"] * 600, depthshade=False)
        for c in entity["cubes"]:
            _box(ax, _xyz(c["pose"]["position"]), _xyz(c["size"]), _rgba(c["color"]))
        for c in entity["cylinders"]:
            _cylinder(ax, _xyz(c["pose"]["position"]), _xyz(c["size"]), _rgba(c["color"]))
        for t in entity["texts"]:
            ax.text(*_xyz(t["pose"]["position"]), t["text"], color="black", fontsize=7)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the recording, the output and the moment."""
    parser.add_argument("recording", type=Path, help="a JSON MCAP (cbgo export, cbgo record "
                                                     "--encoding json)")
    parser.add_argument("output", type=Path, help="the PNG to write")
    parser.add_argument("--at", type=float, default=None, metavar="SECONDS",
                        help="seconds into the file [the last moment with hands, objects and "
                             "a target]")


def run(args: argparse.Namespace) -> int:
    """Draws the chosen moment and writes the PNG."""
    t, entities = pick(args.recording, args.at)
    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(projection="3d")
    draw(entities, ax)
    ax.set_xlabel("x (m, towards the user)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m, up)")
    ax.set_xlim(0.0, 1.1)
    ax.set_ylim(-0.45, 0.45)
    ax.set_zlim(0.0, 0.6)
    ax.set_box_aspect((1.1, 0.9, 0.6))
    ax.view_init(elev=22, azim=-150)
    fig.suptitle("matplotlib rendering of one moment of foxglove/scene (foxglove.SceneUpdate)\n"
                 f"{t:.2f} s into the file; entities {', '.join(sorted(entities))}; "
                 "not a Foxglove screenshot",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    print(f"{args.output}: moment {t:.3f} s, entities {sorted(entities)}")
    return 0
