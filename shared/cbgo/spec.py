"""The schema nodes of the wire contract: plain data that validates a decoded message.

A schema is a tree of nodes (`Obj`, `ListOf`, `Num`, ...). Each node checks one value and
raises `RejectedMessage` naming the field path (``hands[0].palm_position[2]``) and what was
expected. `cbgo.wire` builds one schema per message from these; `cbgo.json_schema` and the
protocol document read the same trees.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from cbgo.errors import RejectedMessage


class Spec:
    """A schema node: `check(value, path)` raises RejectedMessage or returns None."""

    description = "a value"

    def check(self, value: Any, path: str) -> None:  # pragma: no cover - abstract
        """Raises RejectedMessage if `value` does not fit this node."""
        raise NotImplementedError

    def fail(self, value: Any, path: str, expected: str | None = None) -> None:
        """Raises the standard 'expected X, got Y' rejection."""
        raise RejectedMessage(
            f"expected {expected or self.description}, got {show_value(value)}", path)


def show_value(value: Any) -> str:
    """Returns a value's type and the start of its repr, for rejection messages."""
    text = repr(value)
    kind = type(value).__name__
    return f"{kind} {text[:60]}{'...' if len(text) > 60 else ''}"


class AnyValue(Spec):
    """Anything msgpack can carry."""

    description = "any value"

    def check(self, value: Any, path: str) -> None:
        """Accepts every value."""


@dataclass
class Num(Spec):
    """A finite int or float (never bool), optionally within [lo, hi]."""

    lo: float | None = None
    hi: float | None = None

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        if self.lo is not None and self.hi is not None:
            return f"a finite number in [{self.lo}, {self.hi}]"
        if self.lo is not None:
            return f"a finite number >= {self.lo}"
        return "a finite number"

    def check(self, value: Any, path: str) -> None:
        """Rejects non-numbers, bools, NaN, inf and values out of range."""
        if type(value) is float:
            if not math.isfinite(value):
                self.fail(value, path)
        elif type(value) is not int:
            self.fail(value, path)
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            self.fail(value, path)


@dataclass
class Int(Spec):
    """An integer (never bool), optionally within [lo, hi]."""

    lo: int | None = None
    hi: int | None = None

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        if self.lo is not None and self.hi is not None:
            return f"an integer in [{self.lo}, {self.hi}]"
        return "an integer" if self.lo is None else f"an integer >= {self.lo}"

    def check(self, value: Any, path: str) -> None:
        """Rejects non-integers and values out of range."""
        if type(value) is not int or (self.lo is not None and value < self.lo) or (
                self.hi is not None and value > self.hi):
            self.fail(value, path)


@dataclass
class Str(Spec):
    """A string; `choices` restricts it to an enumeration; `nonempty` forbids ''."""

    choices: tuple[str, ...] | None = None
    nonempty: bool = True

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        return "a non-empty string" if self.nonempty else "a string"

    def check(self, value: Any, path: str) -> None:
        """Rejects non-strings, empty strings and values outside the enumeration."""
        if type(value) is not str or (self.nonempty and not value):
            self.fail(value, path)
        if self.choices and value not in self.choices:
            self.fail(value, path)


class Bool(Spec):
    """True or False."""

    description = "a boolean"

    def check(self, value: Any, path: str) -> None:
        """Rejects everything but bool."""
        if type(value) is not bool:
            self.fail(value, path)


class Bytes(Spec):
    """A msgpack bin (Python bytes)."""

    description = "bytes (msgpack bin)"

    def check(self, value: Any, path: str) -> None:
        """Rejects everything but bytes."""
        if not isinstance(value, bytes):
            self.fail(value, path)


@dataclass
class Nullable(Spec):
    """None or a value of `inner`."""

    inner: Spec

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        return f"null or {self.inner.description}"

    def check(self, value: Any, path: str) -> None:
        """Accepts None, else defers to the inner node (saying that null was allowed)."""
        if value is None:
            return
        try:
            self.inner.check(value, path)
        except RejectedMessage as e:
            if e.path != path or not e.problem.startswith("expected "):
                raise
            raise RejectedMessage("expected null or " + e.problem[len("expected "):],
                                  path) from None


@dataclass
class Vec(Spec):
    """A list of exactly `n` finite numbers (positions are Vec(3))."""

    n: int = 3

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        return f"a list of {self.n} finite numbers"

    def check(self, value: Any, path: str) -> None:
        """Rejects lists of the wrong length or with non-finite entries."""
        if type(value) is not list or len(value) != self.n:
            self.fail(value, path)
        for i, x in enumerate(value):
            if type(x) is float:
                if not math.isfinite(x):
                    self.fail(x, f"{path}[{i}]", "a finite number")
            elif type(x) is not int:
                self.fail(x, f"{path}[{i}]", "a finite number")


@dataclass
class ListOf(Spec):
    """A list whose items all fit `item`, with a length between lo and hi."""

    item: Spec
    lo: int = 0
    hi: int | None = None

    @property
    def description(self) -> str:  # type: ignore[override]
        """What this node expects, for error messages and docs."""
        if self.hi is not None and self.hi == self.lo:
            return f"a list of exactly {self.lo} items"
        if self.hi is not None:
            return f"a list of {self.lo} to {self.hi} items"
        return "a list" + (f" of at least {self.lo} items" if self.lo else "")

    def check(self, value: Any, path: str) -> None:
        """Checks the length, then every item."""
        if type(value) is not list:
            self.fail(value, path)
        if len(value) < self.lo or (self.hi is not None and len(value) > self.hi):
            raise RejectedMessage(f"expected {self.description}, got {len(value)} items", path)
        for i, item in enumerate(value):
            self.item.check(item, f"{path}[{i}]")


@dataclass
class MapOf(Spec):
    """A map from non-empty strings to values that fit `value`."""

    value: Spec

    description = "a map with string keys"

    def check(self, value: Any, path: str) -> None:
        """Checks every key is a string and every value fits."""
        if not isinstance(value, dict):
            self.fail(value, path)
        for k, v in value.items():
            if type(k) is not str or not k:
                self.fail(k, path, "non-empty string keys")
            self.value.check(v, f"{path}.{k}")


@dataclass
class Obj(Spec):
    """A map with named fields; unknown fields are tolerated.

    Attributes:
        fields: required fields and their specs.
        optional: fields that may be absent (when present they must fit).
        rules: whole-object checks run after the fields, e.g. names and probs of equal length;
            each returns None or raises RejectedMessage with a path relative to the object.
    """

    fields: dict[str, Spec]
    optional: dict[str, Spec] = field(default_factory=dict)
    rules: tuple[Callable[[dict], None], ...] = ()

    description = "a map"

    def check(self, value: Any, path: str) -> None:
        """Checks required and present optional fields, then the rules."""
        if not isinstance(value, dict):
            self.fail(value, path)
        for name, spec in self.fields.items():
            if name not in value:
                raise RejectedMessage(f"missing required field (expected {spec.description})",
                                      _join(path, name))
            spec.check(value[name], _join(path, name))
        for name, spec in self.optional.items():
            if name in value:
                spec.check(value[name], _join(path, name))
        for rule in self.rules:
            try:
                rule(value)
            except RejectedMessage as e:
                raise RejectedMessage(e.problem, _join(path, e.path)) from None


def _join(path: str, name: str) -> str:
    if not name:
        return path
    return f"{path}.{name}" if path and not name.startswith("[") else f"{path}{name}"
