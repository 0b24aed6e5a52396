"""Reproduce the paper's model comparison and learning curve, with cbgo's model and D5 added.

1. **Model comparison** (the paper's Fig. "Model comparison"): the paper's fixed-slot Bayesian
   networks M1–M5 and cbgo's order-invariant model, trained on ``--train`` observations
   (default 4000, as the paper) of each dataset D1–D5 and tested on ``--test`` fresh ones
   (default 2000), over ``--seeds`` seeds (default 3): accuracy of the action, mean ± std
   over seeds. For cbgo's model also the joint accuracy of its decision (the most probable
   feasible (action, object) pair; moves and place right when the action is) and the expected
   calibration error (ECE) of the decision's confidence. The paper's own figures are printed
   alongside.
2. **Learning curve** on D4 (the paper's Fig. "Accuracy of models trained on D4"): accuracy
   against the number of training observations (``--sizes``) for ``--curve-models``.

Every model gets the same budget (`cbgo.services.intent.models.STEPS` gradient steps, at most
60 s each) and trains single-threaded; ``--jobs`` runs that many trainings at once. Printed:
both tables; saved to ``--out``: ``model_comparison.png``, ``learning_curve.png`` and
``results.json`` (also ``--json``). ``--quick`` is a smoke test (1 seed, small data);
``--from-json`` prints and plots a saved ``results.json`` again without training.

Examples::

    cbgo bench intent                       # the full reproduction (tens of minutes)
    cbgo bench intent --quick
    cbgo bench intent --jobs 2 --out out/bench-intent --json /tmp/intent.json
    cbgo bench intent --from-json out/bench-intent/results.json --out /tmp/replot
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from cbgo.services.intent import datasets
from cbgo.services.intent.models import MODEL_KINDS, STEPS
from cbgo_tools.intent.train import evaluate, fit

# The paper's code's recorded test accuracies (%) (shared/data/README.md), for comparison.
PAPER = {
    "M1": {"D1": "99.2-99.4", "D4": "72"},
    "M2": {"D1": "99.6", "D2": "99.2", "D3": "79.1", "D4": "79.2"},
    "M3": {"D1": "99.6", "D2": "84.1", "D3": "87.7", "D4": "78.8"},
    "M4": {"D1": "99.6", "D2": "99.5", "D3": "97.7±0.2", "D4": "92.6±4.6"},
    "M5": {"D1": "99.3±0.3", "D2": "99.4", "D3": "97.1±0.3", "D4": "97.4", "D5": "92.6"},
}
TIME_LIMIT_S = 60.0  # per training: the budget the comparison promises
GOALS = {"D4 joint": 0.995, "D5 joint": 0.99, "D4@1000 joint": 0.97, "ECE": 0.03}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--seeds", type=int, default=3, help="seeds per cell [3]")
    parser.add_argument("--train", type=int, default=4000, help="training observations [4000]")
    parser.add_argument("--test", type=int, default=2000, help="fresh test observations [2000]")
    parser.add_argument("--datasets", default=",".join(datasets.DATASETS),
                        help="datasets to compare on [D1,...,D5]")
    parser.add_argument("--models", default=",".join(MODEL_KINDS),
                        help="models to compare [M1,...,M5,ours]")
    parser.add_argument("--sizes", default="100,200,300,500,1000,2000,3000,4000",
                        help="learning-curve training sizes on D4 ['' for none]")
    parser.add_argument("--curve-models", default="M4,M5,ours",
                        help="models of the learning curve [M4,M5,ours]")
    parser.add_argument("--steps", type=int, default=STEPS,
                        help=f"gradient steps per training [{STEPS}]")
    parser.add_argument("--jobs", type=int, default=1, help="trainings at once [1]")
    parser.add_argument("--out", type=Path, default=Path("out/bench-intent"),
                        help="folder for the PNG plots and results.json [out/bench-intent]")
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    parser.add_argument("--quick", action="store_true",
                        help="smoke test: 1 seed, 600 train, 400 test, sizes 100,300,600")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="print and plot the results.json of an earlier run (no training)")


@dataclass(frozen=True)
class Job:
    """One training and evaluation."""

    kind: str
    dataset: str
    seed: int
    n: int
    steps: int


def _data(name: str, seed: int, n_train: int, n_test: int
          ) -> tuple[datasets.Dataset, datasets.Dataset]:
    # Train and test are independent draws; seeds differ per dataset, seed and role.
    base = 1000 * seed + 10 * datasets.DATASETS.index(name)
    return (datasets.make(name, n_train, base + 1), datasets.make(name, n_test, base + 2))


def _run_job(job: Job, train: datasets.Dataset, test: datasets.Dataset) -> dict[str, Any]:
    model, seconds = fit(job.kind, train.subset(slice(0, job.n)), job.steps, job.seed,
                         time_limit_s=TIME_LIMIT_S)
    return {"model": job.kind, "dataset": job.dataset, "seed": job.seed, "n": job.n,
            "seconds": seconds, **evaluate(model, test)}


def run_jobs(jobs: list[Job], data: dict, n_jobs: int) -> list[dict[str, Any]]:
    """Runs the trainings (in `n_jobs` processes when more than 1) with a progress bar."""
    bar = tqdm(total=len(jobs), desc="training", unit="model", file=sys.stderr)
    out = []
    if n_jobs <= 1:
        for job in jobs:
            bar.set_postfix_str(f"{job.kind} {job.dataset} n={job.n} seed={job.seed}")
            out.append(_run_job(job, *data[(job.dataset, job.seed)]))
            bar.update()
    else:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(n_jobs, mp_context=context) as pool:
            futures = [pool.submit(_run_job, job, *data[(job.dataset, job.seed)])
                       for job in jobs]
            for future in futures:
                out.append(future.result())
                bar.update()
    bar.close()
    return out


def _cell(results: list[dict], model: str, dataset: str, n: int, key: str) -> np.ndarray:
    return np.array([r[key] for r in results if r["model"] == model and r["dataset"] == dataset
                     and r["n"] == n and key in r])


def _fmt(values: np.ndarray, scale: float = 100.0, digits: int = 1) -> str:
    if not len(values):
        return "-"
    return f"{scale * values.mean():.{digits}f} ± {scale * values.std():.{digits}f}"


def comparison_table(results: list[dict], models: list[str], names: list[str], n: int) -> str:
    """Returns the model comparison as a text table (accuracy %, mean ± std over seeds)."""
    width = 15
    lines = ["model".ljust(14) + "".join(d.rjust(width) for d in names)]
    for model in models:
        lines.append(model.ljust(14) + "".join(_fmt(_cell(results, model, d, n, "action"))
                                                .rjust(width) for d in names))
    if "ours" in models:
        lines.append("ours joint".ljust(14) + "".join(
            _fmt(_cell(results, "ours", d, n, "joint"), digits=2).rjust(width) for d in names))
        lines.append("ours ECE".ljust(14) + "".join(
            _fmt(_cell(results, "ours", d, n, "ece"), 1.0, 3).rjust(width) for d in names))
    lines.append("")
    lines.append("paper (its code's recorded accuracy, %):")
    for model in [m for m in models if m in PAPER]:
        lines.append(model.ljust(14) + "".join(PAPER[model].get(d, "-").rjust(width)
                                                for d in names))
    return "\n".join(lines)


def curve_table(results: list[dict], models: list[str], sizes: list[int]) -> str:
    """Returns the D4 learning curve as a text table (accuracy %, mean ± std)."""
    width = 15
    lines = ["n train".ljust(10) + "".join(m.rjust(width) for m in models)
             + ("ours joint".rjust(width) if "ours" in models else "")]
    for n in sizes:
        row = "".join(_fmt(_cell(results, m, "D4", n, "action")).rjust(width) for m in models)
        if "ours" in models:
            row += _fmt(_cell(results, "ours", "D4", n, "joint"), digits=2).rjust(width)
        lines.append(str(n).ljust(10) + row)
    return "\n".join(lines)


def plot(results: list[dict], models: list[str], names: list[str], n: int,
         curve_models: list[str], sizes: list[int], out: Path) -> list[Path]:
    """Saves the model comparison bar chart and the learning curve as PNGs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(models)
    for i, model in enumerate(models):
        key = "joint" if model == "ours" else "action"
        means = [100 * _cell(results, model, d, n, key).mean() for d in names]
        stds = [100 * _cell(results, model, d, n, key).std() for d in names]
        ax.bar(np.arange(len(names)) + (i - (len(models) - 1) / 2) * width, means, width,
               yerr=stds, capsize=2, label=model if model != "ours" else "ours (joint)")
    ax.set_xticks(np.arange(len(names)), names)
    ax.set_ylim(50, 101)
    ax.set_ylabel("test accuracy (%)")
    ax.set_title(f"Model comparison: {n} training observations, mean ± std over seeds")
    ax.legend(ncol=len(models), fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08))
    ax.grid(axis="y", alpha=0.3)
    paths.append(out / "model_comparison.png")
    fig.tight_layout()
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    if sizes:
        fig, ax = plt.subplots(figsize=(6, 4))
        for model in curve_models:
            key = "joint" if model == "ours" else "action"
            means = np.array([100 * _cell(results, model, "D4", s, key).mean() for s in sizes])
            stds = np.array([100 * _cell(results, model, "D4", s, key).std() for s in sizes])
            ax.plot(sizes, means, marker="o", label=model if model != "ours" else "ours (joint)")
            ax.fill_between(sizes, means - stds, means + stds, alpha=0.2)
        ax.set_xscale("log")
        ax.set_xticks(sizes, [str(size) for size in sizes], fontsize=8)
        ax.minorticks_off()
        ax.set_xlabel("training observations (D4)")
        ax.set_ylabel("test accuracy (%)")
        ax.set_title("Learning curve on D4")
        ax.grid(alpha=0.3)
        ax.legend()
        paths.append(out / "learning_curve.png")
        fig.tight_layout()
        fig.savefig(paths[-1], dpi=120)
        plt.close(fig)
    return paths


def goals(results: list[dict], n: int) -> dict[str, dict[str, float]]:
    """Returns cbgo's model's figures against the goals."""
    figures = {"D4 joint": _cell(results, "ours", "D4", n, "joint"),
               "D5 joint": _cell(results, "ours", "D5", n, "joint"),
               "D4@1000 joint": _cell(results, "ours", "D4", 1000, "joint"),
               "ECE": _cell(results, "ours", "D4", n, "ece")}
    return {k: {"mean": float(v.mean()), "std": float(v.std()), "goal": GOALS[k],
                "met": bool(v.mean() <= GOALS[k] if k == "ECE" else v.mean() >= GOALS[k])}
            for k, v in figures.items() if len(v)}


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark (or re-reports a saved one); returns 0."""
    if args.quick:
        args.seeds, args.train, args.test, args.sizes = 1, 600, 400, "100,300,600"
    names = [d for d in args.datasets.split(",") if d]
    models = [m for m in args.models.split(",") if m]
    curve_models = [m for m in args.curve_models.split(",") if m]
    sizes = [int(s) for s in args.sizes.split(",") if s]
    for name in names:
        datasets.check_name(name)
    started = time.perf_counter()
    if args.from_json is not None:
        saved = json.loads(args.from_json.read_text())
        results = saved["results"]
        args.train, args.test, args.seeds = saved["train"], saved["test"], saved["seeds"]
    else:
        results = _train_all(args, names, models, curve_models, sizes)
    report(results, args, names, models, curve_models, sizes, time.perf_counter() - started)
    return 0


def _train_all(args: argparse.Namespace, names: list[str], models: list[str],
               curve_models: list[str], sizes: list[int]) -> list[dict[str, Any]]:
    needed = set(names) | ({"D4"} if sizes else set())
    data = {(name, seed): _data(name, seed, max([args.train, *sizes]), args.test)
            for name in tqdm(sorted(needed), desc="generating data", file=sys.stderr)
            for seed in range(args.seeds)}
    jobs = [Job(m, d, s, args.train, args.steps) for s in range(args.seeds) for d in names
            for m in models]
    jobs += [Job(m, "D4", s, n, args.steps) for s in range(args.seeds) for n in sizes
             for m in curve_models if not (n == args.train and "D4" in names and m in models)]
    return run_jobs(jobs, data, args.jobs)


def report(results: list[dict], args: argparse.Namespace, names: list[str], models: list[str],
           curve_models: list[str], sizes: list[int], seconds: float) -> None:
    """Prints the tables, the goals and the training times; saves the plots and the JSON."""
    print(f"\nModel comparison: test accuracy (%) of the action, {args.train} training and "
          f"{args.test} fresh test observations, mean ± std over {args.seeds} seed(s)\n")
    print(comparison_table(results, models, names, args.train))
    if sizes:
        print(f"\nLearning curve on D4: test accuracy (%), {args.test} test observations\n")
        print(curve_table(results, curve_models, sizes))
    met = goals(results, args.train)
    if met:
        print("\ncbgo's model against the goals:")
        for key, v in met.items():
            unit, scale = ("", 1.0) if key == "ECE" else (" %", 100.0)
            print(f"  {key:<14} {scale * v['mean']:.3f} ± {scale * v['std']:.3f}{unit}  "
                  f"(goal {'≤' if key == 'ECE' else '≥'} {scale * v['goal']:g}{unit}: "
                  f"{'met' if v['met'] else 'NOT met'})")
    times = [r["seconds"] for r in results]
    by_model = {m: float(np.mean([r["seconds"] for r in results if r["model"] == m]))
                for m in sorted({r["model"] for r in results})}
    print(f"\ntraining time per model: mean {np.mean(times):.1f} s, max {np.max(times):.1f} s "
          f"({', '.join(f'{m} {s:.1f} s' for m, s in by_model.items())}); "
          f"this run {seconds:.0f} s")
    paths = plot(results, models, names, args.train, curve_models, sizes, args.out)
    saved = {"train": args.train, "test": args.test, "seeds": args.seeds, "steps": args.steps,
             "results": results, "goals": met, "paper": PAPER}
    for path in [args.out / "results.json", args.json]:
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(saved, indent=1) + "\n")
    print("saved " + ", ".join(str(p) for p in [*paths, args.out / "results.json"]))
