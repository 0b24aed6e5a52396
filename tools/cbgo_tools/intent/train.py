"""Train an intent model and write it where the intent service loads it.

By default: cbgo's order-invariant model on 8000 observations of D4 (seed 0) with repairable
intents (``--repairable``, see `cbgo.services.intent.datasets`: the planner opens a closed
drawer, sets a held object aside), checked on 2000 fresh observations of the paper's D4 and
2000 of D4 with repairable intents, written to the data directory (`cbgo.config.data_dir`:
``CBGO_DATA_DIR``, else ``~/.local/share/cbgo``) as ``<data dir>/models/intent-ours`` (``.pt``
state_dict + ``.json`` metadata), which the intent service serves before its shipped default.
Trainers never write into the installed package; the shipped default model
(``services/intent/models/ours``) is this command with ``--out services/intent/models/ours``.

Examples::

    cbgo train intent                              # <data dir>/models/intent-ours: served
    cbgo train intent --out services/intent/models/ours   # rebuild the shipped model (checkout)
    cbgo train intent --no-repairable --out /tmp/ours-paper   # the paper's D4 only
    cbgo train intent --dataset D5 -n 4000 --out /tmp/ours-d5
    cbgo train intent --model M5 --out /tmp/m5     # one of the paper's fixed-slot models
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import decide_arrays, joint_correct
from cbgo.services.intent.main import user_model_path
from cbgo.services.intent.models import (
    MODEL_KINDS,
    STEPS,
    Batch,
    OursModel,
    SlotModel,
    new_model,
    train_config,
)

MODEL_ID = "intent-ours-1"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer's flags."""
    parser.add_argument("--model", choices=MODEL_KINDS, default="ours",
                        help="which model [ours]")
    parser.add_argument("--dataset", choices=datasets.DATASETS, default="D4",
                        help="training data [D4]")
    parser.add_argument("-n", "--samples", type=int, default=8000,
                        help="training observations [8000]")
    parser.add_argument("--test", type=int, default=2000, help="fresh test observations [2000]")
    parser.add_argument("--seed", type=int, default=0, help="random seed [0]")
    parser.add_argument("--steps", type=int, default=STEPS,
                        help=f"gradient steps [{STEPS}]")
    parser.add_argument("--repairable", action=argparse.BooleanOptionalAction, default=True,
                        help="also train on intents the planner makes feasible (put into a "
                             "closed drawer, pick up while holding) [on]")
    parser.add_argument("--out", type=Path, default=None,
                        help="model path without suffix [<data dir>/models/intent-<model>]")


def default_out(kind: str) -> Path:
    """Returns where a model of `kind` is written by default: the data directory.

    ``<data dir>/models/intent-<kind>``; the service serves ``intent-ours`` from there before
    its shipped default (`cbgo.services.intent.main.served_model_path`).
    """
    return user_model_path(kind)


def evaluate(model: OursModel | SlotModel, test: datasets.Dataset,
             accept_repairable: bool = False) -> dict[str, float]:
    """Returns accuracy figures of a trained model on a test dataset.

    ``action`` is the argmax of p(action) (the paper's accuracy); for cbgo's model also
    ``joint`` (the decision over feasible (action, object) pairs, right when the action and —
    unless it ignores objects — the object are) and ``ece`` of the decision's confidence.
    With `accept_repairable` the decision also lets the repairable pairs compete (the intent
    service's ``--accept-repairable``), and ``repaired`` is the joint accuracy on the
    observations whose intent needs repairs.
    """
    batch = Batch.from_dataset(test)
    pred = model.predict(batch)
    out = {"action": float(np.mean(pred.p_action.argmax(1) == test.action))}
    if pred.joint is not None:
        allowed = test.feasible | test.repairable if accept_repairable else test.feasible
        action, slot, confidence = decide_arrays(pred.joint, allowed, batch.mask)
        right = joint_correct(action, slot, test.action, test.target)
        out["joint"] = float(right.mean())
        out["ece"] = decision_ece(confidence, right)
        out["mean_confidence"] = float(confidence.mean())
        if accept_repairable and test.repaired.any():
            out["repaired"] = float(right[test.repaired].mean())
    return out


def decision_ece(confidence: np.ndarray, right: np.ndarray, bins: int = 15) -> float:
    """Returns the expected calibration error of decisions (equal-width confidence bins).

    Like `cbgo.metrics.expected_calibration_error`, for a decision's confidence (the chosen
    pair's probability) and whether it was right, rather than a class-probability matrix.
    """
    edges = np.linspace(0.0, 1.0, bins + 1)
    ece = 0.0
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (confidence > lo) & (confidence <= hi)
        if inside.any():
            ece += inside.mean() * abs(confidence[inside].mean() - right[inside].mean())
    return float(ece)


def fit(kind: str, train: datasets.Dataset, steps: int = STEPS, seed: int = 0,
        progress: bool | str = False, time_limit_s: float | None = None
        ) -> tuple[OursModel | SlotModel, float]:
    """Trains a model of `kind` on a dataset; returns it and the training time (s).

    Without a time limit the result depends only on the data and the seed (single-threaded
    torch); with one, a slow machine stops training early.
    """
    torch.set_num_threads(1)  # tiny networks: threads only cost
    model = new_model(kind)
    batch = Batch.from_dataset(train)
    config = train_config(len(train), steps=steps, seed=seed, time_limit_s=time_limit_s)
    started = time.perf_counter()
    if isinstance(model, OursModel):
        model.fit(batch, train.action, train.target, config, progress)
    else:
        model.fit(batch, train.action, config, progress)
    return model, time.perf_counter() - started


def run(args: argparse.Namespace) -> int:
    """Generates the data, trains, evaluates, writes the model; returns the exit code."""
    train = datasets.make(args.dataset, args.samples, args.seed, progress=True,
                          repairable=args.repairable)
    model, seconds = fit(args.model, train, args.steps, args.seed,
                         progress=f"training {args.model}")
    figures = {"test": evaluate(model, datasets.make(args.dataset, args.test,
                                                     args.seed + 1000, progress=True))}
    if args.repairable:  # a third seed: fresh observations with repairable intents
        figures["test_repairable"] = evaluate(model, datasets.make(
            args.dataset, args.test, args.seed + 2000, progress=True, repairable=True),
            accept_repairable=True)
    repairable_flag = "--repairable" if args.repairable else "--no-repairable"
    model.meta.update(
        model_id=MODEL_ID if args.model == "ours" else f"intent-{args.model}",
        gestures=train.meta["gestures"], users=train.meta["users"],
        actions=train.meta["actions"], cell_size_m=train.meta["cell_size_m"],
        trained_on={"dataset": args.dataset, "samples": args.samples, "seed": args.seed,
                    "steps": args.steps, "repairable": args.repairable,
                    "repaired_samples": int(train.repaired.sum()),
                    "tables_sha256": train.meta["tables_sha256"]},
        train_seconds=round(seconds, 1), **figures,
        command=f"cbgo train intent --model {args.model} --dataset {args.dataset} "
                f"-n {args.samples} --seed {args.seed} --steps {args.steps} {repairable_flag}")
    out = args.out or default_out(args.model)
    model.save(out)
    print(f"{args.model} on {args.dataset} ({args.samples} observations, seed {args.seed}, "
          f"{int(train.repaired.sum())} needing repairs): trained in {seconds:.1f} s")
    for name, values in figures.items():
        shown = ", ".join(f"{k} {v:.4f}" for k, v in values.items())
        print(f"  {name} ({args.test} fresh observations): {shown}")
    print(f"wrote {out.with_suffix('.pt')} and {out.with_suffix('.json')}")
    return 0
