"""A stated gesture mapping against learning the same meaning from corrections only.

Examples::

    cbgo bench intent-mapping                        # the three users, about 5-10 minutes
    cbgo bench intent-mapping --users swap_updown --max-corrections 10

Each user (`USERS`) gestures like one of D4's simulated users except where their rules say
otherwise (`mapping.apply` writes the rules into that user's D4 table); their episodes are
drawn from that table. Two ways for the intent service to learn it, both through the
service's own `PersonalStore` (the same fine-tuning, replay and decision):

- **stated**: the user states the rules (`cbgo mapping set`, the page, or the file); the
  user's model is fitted to them before their first episode;
- **corrections only**: the user gestures in the contexts the rules cover (the episodes where
  their meaning differs from the default); each episode the service does not accept as
  intended is corrected (`cbgo feedback`), which refits the user's model.

Printed per user: the share of fresh episodes in the stated contexts that the service accepts
as intended ("followed"; ``--eval`` of them, seed ``--seed``), with the default model, with the
stated mapping from the first episode, and, for corrections only, after each correction; the
episodes and corrections it took until `GOAL_FOLLOWED` of them were followed (at most
``--max-corrections`` corrections); and the share of all the user's fresh episodes followed
(the rest of the convention must not be forgotten). Every episode is drawn where the scene
allows the intended action (the data sets draw only feasible intents).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig, decide
from cbgo.services.intent.main import default_model_path
from cbgo.services.intent.mapping import GestureMapping, Rule, apply, check
from cbgo.services.intent.models import Batch, OursModel
from cbgo.services.intent.personal import Correction, PersonalStore
from cbgo.world import OBJECT_AGNOSTIC

GOAL_FOLLOWED = 0.99  # share of the stated contexts' fresh episodes followed
# Users whose meanings differ from a D4 profile's: (profile, rules).
USERS: dict[str, tuple[str, tuple[Rule, ...]]] = {
    # thumbs-up on a cup means pour (user1's thumbs-up places it)
    "thumbs_pour": ("user1", (Rule("thumbsup", "pour", "cup"),)),
    # point and grab swapped: point picks up and opens, grab places on a drawer
    "swap_grab_point": ("user1", (Rule("point", "pick_up", "cup"), Rule("point", "pick_up", "box"),
                                  Rule("point", "open", "drawer"),
                                  Rule("grab", "place", "drawer"))),
    # swipe up and down swapped
    "swap_updown": ("user2", (Rule("swipe_up", "move_down"), Rule("swipe_down", "move_up"))),
}
SERVICE_DECISION = DecisionConfig(clarify=False)  # followed = accepted as intended, unasked


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--users", default=",".join(USERS),
                        help=f"users to measure [{','.join(USERS)}]")
    parser.add_argument("--eval", type=int, default=400,
                        help="fresh episodes in the stated contexts per user [400]")
    parser.add_argument("--all", type=int, default=1500,
                        help="fresh episodes in every context per user [1500]")
    parser.add_argument("--max-corrections", type=int, default=20,
                        help="corrections-only learning stops after this many [20]")
    parser.add_argument("--seed", type=int, default=9000, help="seed of the fresh episodes [9000]")
    parser.add_argument("--model", default=None,
                        help="an intent model (<base>.json); default: the shipped one")


def stated_contexts(mapping: GestureMapping) -> set[tuple[str, int, str]]:
    """(object type, state bit, gesture) of every context a rule covers."""
    return {(t, bit, r.gesture) for r in mapping.rules for t, bit in r.contexts()}


def wanted(sample: datasets.Sample) -> tuple[str, str | None]:
    """The intended (action, object) as the decision names it."""
    return sample.action, None if sample.action in OBJECT_AGNOSTIC else sample.target


def followed(model: OursModel, user_vector: np.ndarray,
             items: Sequence[datasets.Sample]) -> np.ndarray:
    """(N,) whether the service's decision accepts each episode as intended."""
    if not items:
        return np.zeros(0, bool)
    batch = Batch.from_dataset(datasets.to_dataset(items)).with_user(user_vector)
    joint = model.predict(batch, samples=32).joint
    out = []
    for i, s in enumerate(items):
        d = decide(joint[i, :len(s.scene.objects)], s.scene.names, s.scene, SERVICE_DECISION)
        out.append(d.status == "accepted" and (d.action, d.object) == wanted(s))
    return np.array(out)


def correction_of(sample: datasets.Sample, user: str, gestures: Sequence[str]) -> Correction:
    """The correction a user gives for an episode the service got wrong."""
    action, obj = wanted(sample)
    return Correction(user=user, action=action, object=obj,
                      gestures={"names": list(gestures), "probs": sample.g.tolist()},
                      scene=sample.scene.to_dict(), focus=sample.focus.tolist(),
                      context_object=sample.target, ts=time.time())


def model_of(store: PersonalStore, base: OursModel, user: str) -> tuple[OursModel, np.ndarray]:
    """The model and user vector the service uses for `user` now."""
    personal = store.get(user)
    return (personal.model, personal.user_vector) if personal else (base,
                                                                    store.start_vector(user))


def measure(base: OursModel, name: str, profile: str, mapping: GestureMapping,
            args: argparse.Namespace) -> dict:
    """Measures one user: default, stated, and corrections only; prints as it goes."""
    tables = apply(datasets.load_tables(), profile, mapping)
    stated = stated_contexts(mapping)
    in_stated = lambda _a, t, bit, g: (t, bit, g) in stated  # noqa: E731
    seed = args.seed + 10 * list(USERS).index(name)
    evaluation = list(datasets.samples("D4", args.eval, seed, users=[profile], tables=tables,
                                       only=in_stated))
    everything = list(datasets.samples("D4", args.all, seed + 1, users=[profile],
                                       tables=tables))
    print(f"\n{name} (reads as {profile}; " + "; ".join(r.label for r in mapping.rules) + ")")
    store = PersonalStore(None, base, default_profile=profile)
    start = store.start_vector(name)
    default = followed(base, start, evaluation).mean()
    print(f"  default model: stated contexts followed {100 * default:.1f} %, all contexts "
          f"{100 * followed(base, start, everything).mean():.1f} %")
    t0 = time.perf_counter()
    personal = store.set_mapping(name, mapping)
    fit_s = time.perf_counter() - t0
    told = followed(personal.model, personal.user_vector, evaluation).mean()
    told_all = followed(personal.model, personal.user_vector, everything).mean()
    print(f"  stated: from the first episode, stated contexts followed {100 * told:.1f} % "
          f"({args.eval} episodes), all contexts {100 * told_all:.1f} % ({args.all}); "
          f"fitted in {fit_s:.1f} s")
    learnt = by_corrections(base, name, profile, tables, in_stated, evaluation, seed + 2, args)
    model, vector = model_of(learnt["store"], base, name)
    learnt_all = followed(model, vector, everything).mean()
    outcome = (f"reached {100 * GOAL_FOLLOWED:g} % after {learnt['episodes']} episodes "
               f"({learnt['corrections']} corrections)" if learnt["reached"] else
               f"NOT reached after {learnt['episodes']} episodes "
               f"({learnt['corrections']} corrections)")
    print(f"  corrections only: {outcome}; stated contexts followed after each correction: "
          + " ".join(f"{100 * f:.0f}" for f in learnt["curve"]) + " %; all contexts "
          f"{100 * learnt_all:.1f} %; refits {np.mean(learnt['fit_s'] or [0]):.1f} s each")
    return {"default": default, "stated": told, "stated_all": told_all, "learnt": learnt,
            "learnt_all": learnt_all}


def by_corrections(base: OursModel, name: str, profile: str, tables: datasets.Tables,
                   in_stated, evaluation: list[datasets.Sample], seed: int,
                   args: argparse.Namespace) -> dict:
    """The user gestures in the stated contexts and corrects every episode not followed."""
    store = PersonalStore(None, base, default_profile=profile)
    stream = datasets.samples("D4", 100 * args.max_corrections + 100, seed, users=[profile],
                              tables=tables, only=in_stated)
    curve, fit_s, episodes, corrections = [], [], 0, 0
    bar = tqdm(total=args.max_corrections, desc=f"{name} corrections", unit="correction",
               file=sys.stderr)
    reached = False
    for sample in stream:
        episodes += 1
        model, vector = model_of(store, base, name)
        if followed(model, vector, [sample])[0]:
            continue
        t0 = time.perf_counter()
        store.add(correction_of(sample, name, tables.gestures))
        fit_s.append(time.perf_counter() - t0)
        corrections += 1
        bar.update()
        model, vector = model_of(store, base, name)
        curve.append(followed(model, vector, evaluation).mean())
        if curve[-1] >= GOAL_FOLLOWED:
            reached = True
            break
        if corrections >= args.max_corrections:
            break
    bar.close()
    return {"store": store, "curve": curve, "fit_s": fit_s, "episodes": episodes,
            "corrections": corrections, "reached": reached}


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark; returns 0 if every stated mapping meets the goal, else 1."""
    torch.set_num_threads(1)
    started = time.perf_counter()
    names = [n for n in args.users.split(",") if n]
    unknown = [n for n in names if n not in USERS]
    if unknown:
        print(f"unknown user {unknown[0]!r}; known: {', '.join(USERS)}", file=sys.stderr)
        return 2
    path = default_model_path() if args.model is None else Path(args.model).with_suffix(".json")
    base = OursModel.load(path)
    print(f"model {base.name} ({path}); followed = accepted as intended by the service's "
          f"decision; goal: >= {100 * GOAL_FOLLOWED:g} % of the stated contexts from the "
          "first episode")
    results = {n: measure(base, n, *(USERS[n][0], check(GestureMapping(USERS[n][1]))), args)
               for n in names}
    print(f"\n{'user':<18}{'default %':>10}{'stated %':>10}{'all %':>8}"
          f"{'learnt: episodes':>18}{'corrections':>13}{'followed %':>12}{'all %':>8}")
    met = True
    for n, r in results.items():
        learnt = r["learnt"]
        last = learnt["curve"][-1] if learnt["curve"] else r["default"]
        print(f"{n:<18}{100 * r['default']:>10.1f}{100 * r['stated']:>10.1f}"
              f"{100 * r['stated_all']:>8.1f}{learnt['episodes']:>18d}"
              f"{learnt['corrections']:>13d}{100 * last:>12.1f}{100 * r['learnt_all']:>8.1f}")
        met = met and r["stated"] >= GOAL_FOLLOWED
    print(f"\nstated mapping followed from the first episode >= {100 * GOAL_FOLLOWED:g} % for "
          f"every user: {'met' if met else 'NOT met'}")
    print(f"this run {time.perf_counter() - started:.0f} s")
    return 0 if met else 1
