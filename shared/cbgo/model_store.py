"""Which model a service serves, and whether its files changed: one rule for every model.

The three model-serving services (static-gesture, dynamic-gesture, intent) find their model the
same way and take the same flags:

- ``--model PATH`` (env ``CBGO_MODEL``) when given;
- else the person's own model (`ModelStore.personal`, set by a service that follows
  ``cbgo/user``), once all its files are there;
- else the user's model in the data directory (`cbgo.config.data_dir`), where
  ``cbgo train <name>`` writes it, once all its files are there;
- else the model shipped with the package (never written to: an installed package may be
  read-only, as it is in the image).

``--watch-s S`` polls the files every S seconds (their modification time and size; without
``--model`` the choice above is made again each time, so a user's first trained model is picked
up) and the service reloads on a change; a file that does not load is logged and counted once,
and the model in service stays. The control verb ``reload`` reloads at once.

A model is one file or a set of files with one base path (``static-gesture.pt`` +
``static-gesture.json``): `ModelStore.suffixes` says which.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from cbgo.errors import QueryError

WATCH_HELP = ("poll the model files for changes every S seconds and reload them (0: only on "
              "the reload verb)")


def model_help(what: str, user: str, shipped: str) -> str:
    """Returns the ``--model`` help text of a service, the same sentence for all three."""
    return (f"{what}; default: the user's {user} in the data dir (CBGO_DATA_DIR) once "
            f"`cbgo train` wrote it, else the shipped {shipped}")


@dataclass
class ModelStore:
    """Where one service's model comes from (see the module docstring).

    Attributes:
        shipped: the shipped model's base path.
        user: the user's model's base path in the data directory.
        suffixes: the files of one model: each suffix replaces the base path's (``""``: the
            base path itself is the file).
        configured: ``--model``, when given (then the user's and the shipped are not used).
        personal: the base path of the current person's own model, if the service has one
            (served before the user's when all its files are there).
    """

    shipped: Path
    user: Path
    suffixes: tuple[str, ...] = ("",)
    configured: str | None = None
    personal: Path | None = None
    _watched: tuple = field(default=(None, None), repr=False)

    def files(self, base: Path) -> list[Path]:
        """Returns the files of the model at `base`."""
        return [base.with_suffix(s) if s else base for s in self.suffixes]

    def path(self) -> Path:
        """Returns the base path of the model to serve now (chosen again at each call)."""
        if self.configured:
            return Path(self.configured)
        if self.personal is not None and all(f.is_file() for f in self.files(self.personal)):
            return self.personal
        if all(f.is_file() for f in self.files(self.user)):
            return self.user
        return self.shipped

    def stamps(self, base: Path) -> tuple:
        """Returns (mtime_ns, size) of each file of a model (None for a missing one)."""
        out = []
        for f in self.files(base):
            try:
                st = f.stat()
                out.append((st.st_mtime_ns, st.st_size))
            except OSError:
                out.append(None)
        return tuple(out)

    def snapshot(self) -> tuple[Path, tuple]:
        """Returns the model to serve and its stamps, taken BEFORE it is loaded.

        Files replaced while loading then differ from these stamps and are loaded again at the
        next poll.
        """
        path = self.path()
        return path, self.stamps(path)

    def reload_target(self, query: dict) -> tuple[Path, tuple]:
        """Returns what a ``reload`` query asks to load and its stamps, taken before loading.

        ``{model: PATH}`` names another model (adopt it with `switch_to` once it loaded);
        ``{}`` reloads the model chosen now.

        Raises:
            QueryError: ``model`` is not a path string.
        """
        requested = query.get("model")
        if requested is not None and not (isinstance(requested, str) and requested):
            raise QueryError("model must be a path string")
        path = Path(requested) if requested else self.path()
        return path, self.stamps(path)

    def switch_to(self, query: dict) -> str | None:
        """After a reload loaded: serves the query's ``model`` from now on; returns it, if any."""
        if query.get("model"):
            self.configured = query["model"]
        return query.get("model")

    def served(self, path: Path, stamps: tuple) -> None:
        """Records what was loaded (or tried: a broken file is reported once, not each poll)."""
        self._watched = (path, stamps)

    def served_path(self) -> Path | None:
        """Returns the base path of the model last served (or tried), None before any."""
        return self._watched[0]

    def changed(self) -> bool:
        """Returns whether the model to serve moved or its files changed since `served`."""
        return self.snapshot() != self._watched
