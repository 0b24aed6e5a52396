"""Check an intent model on fresh observations and on the end-to-end demo's decisions.

Examples::

    cbgo bench intent-check                   # the shipped model
    cbgo bench intent-check --model /tmp/old/ours --seed 6000
    cbgo bench intent-check --timing 200     # the cost of one inference only

Prints, on observations drawn with seeds neither `cbgo train intent` (0, 1000, 2000) nor
`cbgo bench intent` (below 3000) uses:

1. the paper's D4: action accuracy, joint accuracy and ECE of the decision among feasible
   pairs (what `cbgo train intent` and `cbgo bench intent` report), and the joint accuracy of
   the service's decision, in which repairable intents compete (``--accept-repairable``);
2. intents that need the planner's repairs (D4 drawn with repairable intents, only those): the
   share the service's decision accepts as intended, leaves ``low_confidence``, or decides
   otherwise;
3. the demo's decisions (`CHECKS`) through `IntentEngine`, each against what it should be.

The exit status is 1 if a demo decision differs from what it should be.

``--timing N`` prints instead what one inference costs on the demo's first scene (`CHECKS`):
median and p90 over N repeats of `OursModel.predict` alone and of the whole `IntentEngine.infer`
(scene checks, features, prediction, decision), single-threaded like the service.
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig, decide
from cbgo.services.intent.engine import IntentEngine
from cbgo.services.intent.main import default_model_path
from cbgo.services.intent.models import Batch, OursModel
from cbgo.world import DEFAULT_GRID, OBJECT_AGNOSTIC, Robot, Scene, SceneObject
from cbgo_tools.intent.train import evaluate

SERVICE_DECISION = DecisionConfig()  # the service's defaults are the decision's
# The decision at --min-confidence alone (no asking back above it): what the fresh
# observations' shares report; `cbgo bench intent-clarify` measures the asking.
UNASKED_DECISION = DecisionConfig(ask_below=0.0)


# ==================================================================== the demo's scenes


def on_table(name: str, kind: str, xy: tuple[float, float], size: float,
             **state) -> SceneObject:
    """Returns an object standing on the table at (x, y) m."""
    return SceneObject(name, kind, (xy[0], xy[1], size / 2), size, **state)


def column(i: int, j: int) -> tuple[float, float]:
    """Returns the (x, y) of grid column (i, j)."""
    return DEFAULT_GRID.column_xy((i, j))


def demo_scene(holding: str | None = "cup1") -> Scene:
    """The paper's story: full cup1 (in the gripper by default), empty cup2, closed drawer1, box1.

    With ``holding=None`` cup1 stands on the table and the gripper is empty.
    """
    scene = Scene([on_table("cup1", "cup", column(0, 3), 0.06, full=True),
                   on_table("cup2", "cup", column(1, 2), 0.06),
                   on_table("drawer1", "drawer", column(3, 0), 0.11),
                   on_table("box1", "box", column(2, 3), 0.05)],
                  Robot(DEFAULT_GRID.position((1, 1, 2)), holding is None, holding))
    scene.settle()
    return scene


def two_cups_scene(gap_m: float = 0.2, holding: str | None = None) -> Scene:
    """Two cups `gap_m` apart along y at x = 0.44 m, a closed drawer and a box farther away."""
    scene = Scene([on_table("cup1", "cup", (0.44, -gap_m / 2), 0.06, full=True),
                   on_table("cup2", "cup", (0.44, gap_m / 2), 0.06),
                   on_table("drawer1", "drawer", column(3, 0), 0.11),
                   on_table("box1", "box", column(0, 3), 0.05)],
                  Robot(DEFAULT_GRID.position((1, 1, 2)), holding is None, holding))
    scene.settle()
    return scene


@dataclass(frozen=True)
class Check:
    """One demo decision: a gesture at a point in a scene, and the intent it should give."""

    title: str
    scene: Callable[[], Scene]
    user: str
    gesture: str
    looked_at: str | tuple[float, float, float]  # an object (its centre) or a point
    status: str
    action: str | None
    object: str | None

    def focus(self, scene: Scene) -> list[float]:
        """Returns the focus point: the looked-at object's centre, or the given point."""
        if isinstance(self.looked_at, str):
            return [float(v) for v in scene.get(self.looked_at).position]
        return list(self.looked_at)


CHECKS = (
    Check("user1 five at the closed drawer, holding full cup1", demo_scene, "user1", "five",
          "drawer1", "accepted", "put_into", "drawer1"),
    Check("user2 point at the closed drawer, holding full cup1", demo_scene, "user2", "point",
          "drawer1", "accepted", "put_into", "drawer1"),
    Check("user1 grab at the closed drawer, holding full cup1", demo_scene, "user1", "grab",
          "drawer1", "accepted", "open", "drawer1"),
    Check("user1 grab at the closed drawer, gripper empty", lambda: demo_scene(None), "user1",
          "grab", "drawer1", "accepted", "open", "drawer1"),
    Check("user1 grab at cup2, gripper empty", lambda: demo_scene(None), "user1", "grab",
          "cup2", "accepted", "pick_up", "cup2"),
    Check("user1 grab at cup2, holding full cup1", demo_scene, "user1", "grab", "cup2",
          "accepted", "pick_up", "cup2"),
    Check("user1 rotate at empty cup2, holding full cup1", demo_scene, "user1", "rotate",
          "cup2", "accepted", "pour", "cup2"),
    Check("user1 grab halfway between two cups 0.2 m apart", two_cups_scene, "user1", "grab",
          (0.44, 0.0, 0.03), "low_confidence", None, None),
    Check("user1 grab halfway between two cups 0.2 m apart, holding box1",
          lambda: two_cups_scene(holding="box1"), "user1", "grab", (0.44, 0.0, 0.03),
          "low_confidence", None, None),
)


def run_check(engine: IntentEngine, check: Check) -> dict:
    """Returns the intent the engine gives for a check."""
    scene = check.scene()
    return engine.infer({"names": [check.gesture], "probs": [0.9]}, scene.to_dict(),
                        check.focus(scene), check.user)


def check_passes(check: Check, intent: dict, first_offered: tuple | None = None) -> bool:
    """Returns whether an intent is what the check expects.

    An expected accepted intent may also be asked back (below ``--ask-below``) with the
    expected one offered first: the user's thumbs-up then confirms it.
    """
    if check.status == "accepted" and intent.get("clarification") is not None:
        return first_offered == (check.action, check.object)
    return (intent["status"], intent["action"], intent["object"]) == (
        check.status, check.action, check.object)


def offered_first(engine: IntentEngine, intent: dict) -> tuple[str, str | None] | None:
    """Returns the first candidate of the clarification an intent opened, if any."""
    asked = engine.clarifications.open.get(intent.get("clarification"))
    return None if asked is None else (asked.candidates[0].action, asked.candidates[0].object)


# ==================================================================== fresh observations


def repaired_samples(n: int, seed: int) -> list[datasets.Sample]:
    """Returns the first n observations of D4 with repairable intents that need repairs."""
    drawn = datasets.samples("D4", 10**9, seed, repairable=True)
    return list(itertools.islice((s for s in drawn if s.repaired), n))


def service_outcomes(model: OursModel, items: list[datasets.Sample],
                     samples: int) -> Counter:
    """Counts how the service's decision treats observations: intended, low_confidence, other."""
    batch = Batch.from_dataset(datasets.to_dataset(items))
    joint = model.predict(batch, samples=samples).joint
    out: Counter = Counter()
    for i, s in enumerate(items):
        d = decide(joint[i, :len(s.scene.objects)], s.scene.names, s.scene, UNASKED_DECISION)
        out[outcome(d.status, d.action, d.object, s)] += 1
    return out


def outcome(status: str, action: str | None, obj: str | None, s: datasets.Sample) -> str:
    """Names one decision: intended, low_confidence, infeasible or other."""
    if status != "accepted":
        return status
    wanted_object = None if action in OBJECT_AGNOSTIC else s.target
    return "intended" if (action, obj) == (s.action, wanted_object) else "other"


def shares(counts: Counter) -> str:
    """Returns 'name k/n (p %)' for every outcome, intended first."""
    n = sum(counts.values())
    order = ["intended", "low_confidence", "infeasible", "other"]
    return ", ".join(f"{k} {counts[k]}/{n} ({100 * counts[k] / n:.1f} %)" for k in order
                     if counts[k] or k == "intended")


# ==================================================================== command line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the model, the sample sizes and ``--timing``."""
    parser.add_argument("--model", type=Path, default=None,
                        help="model path (<base>.pt + <base>.json) [the shipped model]")
    parser.add_argument("-n", type=int, default=10000,
                        help="fresh observations of the paper's D4 [10000]")
    parser.add_argument("--repaired", type=int, default=500,
                        help="fresh observations whose intent needs repairs; 0: skip [500]")
    parser.add_argument("--seed", type=int, default=5000,
                        help="D4's seed; the repairable ones use seed + 1 [5000]")
    parser.add_argument("--samples", type=int, default=32,
                        help="posterior samples per prediction (the service's default) [32]")
    parser.add_argument("--timing", type=int, default=0, metavar="N",
                        help="only time one inference on the demo's first scene, N repeats")


def run(args: argparse.Namespace) -> int:
    """Prints the three evaluations; returns 1 if a demo decision is not as it should be."""
    torch.set_num_threads(1)  # tiny networks: threads only cost
    model = OursModel.load(args.model or default_model_path())
    if args.timing > 0:
        report_timing(IntentEngine(model, SERVICE_DECISION, None, args.samples), CHECKS[0],
                      args.timing)
        return 0
    trained = model.meta.get("trained_on", {})
    print(f"model {model.name}: {trained.get('dataset')}, {trained.get('samples')} "
          f"observations, repairable intents: {trained.get('repairable', False)}")
    d4_items = list(datasets.samples("D4", args.n, args.seed))
    figures = evaluate(model, datasets.to_dataset(d4_items))
    served = service_outcomes(model, d4_items, args.samples)
    print(f"D4, {args.n} fresh (seed {args.seed}): action {figures['action']:.4f}, joint "
          f"{figures['joint']:.4f}, ECE {figures['ece']:.4f} (decision among feasible pairs)")
    print(f"  service decision (repairable compete, min 0.5, no asking above it): "
          f"{shares(served)}")
    if args.repaired > 0:
        report_repaired(model, repaired_samples(args.repaired, args.seed + 1), args)
    return report_checks(IntentEngine(model, SERVICE_DECISION, None, args.samples))


def report_repaired(model: OursModel, fixes: list[datasets.Sample],
                    args: argparse.Namespace) -> None:
    """Prints how the service's decision treats intents needing repairs, in all and per action."""
    print(f"needing repairs, {len(fixes)} fresh (seed {args.seed + 1}): "
          f"{shares(service_outcomes(model, fixes, args.samples))}")
    for action in sorted({s.action for s in fixes}):
        subset = [s for s in fixes if s.action == action]
        print(f"  {action}: {shares(service_outcomes(model, subset, args.samples))}")


def report_checks(engine: IntentEngine) -> int:
    """Prints every demo decision against what it should be; returns 1 if one differs."""
    failed = 0
    for check in CHECKS:
        intent = run_check(engine, check)
        first = offered_first(engine, intent)
        ok = check_passes(check, intent, first)
        failed += not ok
        got = f"{intent['status']} {intent['action']}({intent['object']})"
        if first is not None:
            got = f"asked back, {first[0]}({first[1]}) offered first"
        print(f"{'ok  ' if ok else 'FAIL'} {check.title}: {got} p={intent['confidence']:.2f}"
              + ("" if ok else f"; should be {check.status} {check.action}({check.object})"))
    return 1 if failed else 0


# ==================================================================== timing


def time_inference(engine: IntentEngine, check: Check, repeats: int) -> dict[str, np.ndarray]:
    """Returns the ms of `repeats` predictions alone and of as many whole inferences."""
    scene = check.scene()
    body, focus = scene.to_dict(), check.focus(scene)  # the service receives the scene's body
    gestures = {"names": [check.gesture], "probs": [0.9]}
    user = np.eye(len(engine.users))[engine.users.index(check.user)]
    batch = Batch.from_scene(scene, engine.gesture_vector(gestures), user, focus, engine.cell)
    run_check(engine, check)  # the first call pays for lazy initialisation: not timed
    return {"predict": _repeat_ms(lambda: engine.model.predict(batch, samples=engine.samples),
                                  repeats),
            "infer": _repeat_ms(lambda: engine.infer(gestures, body, focus, check.user),
                                repeats)}


def _repeat_ms(call: Callable[[], object], repeats: int) -> np.ndarray:
    out = np.empty(repeats)
    for i in range(repeats):
        start = time.perf_counter()
        call()
        out[i] = (time.perf_counter() - start) * 1000
    return out


def report_timing(engine: IntentEngine, check: Check, repeats: int) -> None:
    """Prints median and p90 ms of one prediction and of one whole inference."""
    print(f"one inference, {engine.samples} posterior samples, {check.title}, "
          f"{repeats} repeats:")
    for name, ms in time_inference(engine, check, repeats).items():
        print(f"  {name}: median {np.median(ms):.2f} ms, p90 {np.percentile(ms, 90):.2f} ms")
