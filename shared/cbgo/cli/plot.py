"""Draw figures from recordings; each figure's module parses its own options.

Figures:
    episode          the paper's episode figure: gesture likelihoods (static, dynamic),
                     evidence, hand visibility and triggers of one episode
    foxglove-scene   one moment of a JSON recording's foxglove/scene drawn with matplotlib
                     (the offline tools of a checkout)

Examples::

    cbgo record -o session.mcap --duration 30
    cbgo plot episode session.mcap -o episode.png
    cbgo plot episode session.mcap --list
    cbgo plot episode session.mcap --episode -1 -o last.png
    cbgo plot episode --help          # a figure's own options
"""

from __future__ import annotations

import argparse
import importlib

from cbgo import registry


def _figures() -> dict[str, tuple[str, str]]:
    """Returns figure -> (module, one-line summary), each module with add_arguments and run.

    The services' figures (their manifests' ``figures``), and the offline tools' where a
    checkout has them.
    """
    figures = registry.tools("figures")
    try:
        from cbgo_tools.registry import FIGURES as offline
    except ModuleNotFoundError:  # an installed wheel: no offline tools
        offline = {}
    return {**figures, **offline}


FIGURES = _figures()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the figure name; its own options are parsed by the figure's module (lazy import)."""
    parser.add_argument("figure", choices=sorted(FIGURES), metavar="FIGURE",
                        help="; ".join(f"{name}: {text}" for name, (_, text) in FIGURES.items()))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the figure's own options")


def run(args: argparse.Namespace) -> int:
    """Imports the chosen figure's module, parses its options and draws."""
    module = importlib.import_module(FIGURES[args.figure][0])
    parser = argparse.ArgumentParser(prog=f"cbgo plot {args.figure}", description=module.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    module.add_arguments(parser)
    return module.run(parser.parse_args(args.args))
