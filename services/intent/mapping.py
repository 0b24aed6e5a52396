"""A user's stated gesture mapping: what a gesture means to them, per object type and state.

The file is ``<personal dir>/<user>/mapping.yaml``, beside the user's model and corrections
(`cbgo.services.intent.personal`), edited with ``cbgo mapping``, on the web page, or by hand::

    rules:
      - gesture: swipe_left        # for this user, swipe_left means put_into ...
        action: put_into
      - gesture: thumbsup          # ... and thumbsup on a cup means pour
        action: pour
        on: cup
      - gesture: grab              # a rule can name the object's state too
        action: open
        on: drawer
        state: closed

A rule says which action the gesture asks for wherever it applies (every object type, or the
type ``on`` names, in both states or the ``state`` named). The mapping is a **prior** of the
user's model, not a lookup: the user's convention is the decision table of the profile the user
starts from (`datasets.Tables`, D4) with the rules written into it (`apply`), and the user's
model is fine-tuned on observations drawn from that table (`personal.personalise`). The scene's
feasibility and the gesture evidence still decide each intent; corrections keep refining it.

Precedence: a rule naming a type and a state beats one naming a type, which beats one naming
neither. Two rules of the same gesture, context and precision that ask for different actions
are an error; so is an unknown gesture, action, object type or state (the message names the
known ones), or an action that never applies to the type named.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
from collections.abc import Iterable
from collections.abc import Mapping as MappingABC
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import yaml

from cbgo.errors import ConfigError
from cbgo.services.intent.datasets import Tables, load_tables
from cbgo.wire import ACTIONS, OBJECT_TYPES
from cbgo.world import OBJECT_AGNOSTIC

FILE_NAME = "mapping.yaml"
STATE_NAMES: dict[str, tuple[str, str]] = {  # the paper's state bit 0 and 1, per type
    "cup": ("empty", "full"), "drawer": ("closed", "open"), "box": ("free", "blocked")}
MAX_RULES = 200  # a person states a handful; more is a broken file
RULE_FIELDS = ("gesture", "action", "on", "state")


class MappingError(ConfigError):
    """A mapping that cannot be used; the message says what to fix."""


@dataclass(frozen=True)
class Rule:
    """One statement: `gesture` means `action` (on objects of type `on`, in `state`)."""

    gesture: str
    action: str
    on: str | None = None
    state: str | None = None

    @property
    def precision(self) -> int:
        """0: any object; 1: one type; 2: one type in one state (the higher wins)."""
        return (self.on is not None) + (self.state is not None)

    def contexts(self) -> list[tuple[str, int]]:
        """Returns the (object type, state bit) contexts the rule covers."""
        types = [self.on] if self.on else list(OBJECT_TYPES)
        return [(t, bit) for t in types for bit in (0, 1)
                if self.state is None or STATE_NAMES[t][bit] == self.state]

    @property
    def label(self) -> str:
        """``thumbsup -> pour on cup (empty)``."""
        where = f" on {self.on}" if self.on else ""
        return f"{self.gesture} -> {self.action}{where}" + (f" ({self.state})" if self.state
                                                            else "")

    def to_dict(self) -> dict[str, str]:
        """The rule as the file writes it (absent fields left out)."""
        return {k: v for k, v in asdict(self).items() if v is not None}


@dataclass(frozen=True)
class GestureMapping:
    """A user's rules, in the order stated."""

    rules: tuple[Rule, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.rules)

    def to_dict(self) -> dict[str, Any]:
        """``{rules: [...]}``, the file's content."""
        return {"rules": [r.to_dict() for r in self.rules]}

    def key(self) -> str:
        """A short hash of the rules (which mapping a personal model was fitted to)."""
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_rule(self, rule: Rule) -> GestureMapping:
        """Returns the mapping with `rule` added, replacing one of the same gesture and context."""
        kept = [r for r in self.rules if (r.gesture, r.on, r.state) != (
            rule.gesture, rule.on, rule.state)]
        return check(GestureMapping((*kept, rule)))

    def without(self, gesture: str, on: str | None = None,
                state: str | None = None) -> tuple[GestureMapping, int]:
        """Returns the mapping without the rules of that gesture and context, and how many."""
        kept = tuple(r for r in self.rules if (r.gesture, r.on, r.state) != (gesture, on, state))
        return GestureMapping(kept), len(self.rules) - len(kept)


def _known(what: str, value: Any, known: Iterable[str], where: str) -> str:
    known = list(known)
    if not isinstance(value, str) or value not in known:
        raise MappingError(f"{where}: unknown {what} {value!r}; known {what}s: "
                           f"{', '.join(known)}")
    return value


def applies(action: str, obj_type: str, tables: Tables | None = None) -> bool:
    """Returns whether any user's D4 table lets `action` be asked of an object of `obj_type`."""
    if action in OBJECT_AGNOSTIC:
        return True
    table = (tables or load_tables()).tables["D4"]
    return any(table[s][u][obj_type][action] is not None for s in table for u in table[s])


def parse_rule(raw: Any, where: str, gestures: Iterable[str]) -> Rule:
    """Returns one rule of a file or a command, or raises MappingError naming the problem."""
    if not isinstance(raw, MappingABC):
        raise MappingError(f"{where}: expected a map with gesture and action, got "
                           f"{type(raw).__name__}")
    extra = sorted(set(map(str, raw)) - set(RULE_FIELDS))
    if extra:
        raise MappingError(f"{where}: unknown field {extra[0]!r}; a rule has "
                           f"{', '.join(RULE_FIELDS)}")
    gesture = _known("gesture", raw.get("gesture"), gestures, where)
    action = _known("action", raw.get("action"), ACTIONS, where)
    on = raw.get("on")
    if on is not None:
        _known("object type", on, OBJECT_TYPES, where)
    state = raw.get("state")
    if state is not None:
        if on is None:
            raise MappingError(f"{where}: a state needs an object type (on: cup|drawer|box)")
        _known(f"state of a {on}", state, STATE_NAMES[on], where)
    if on is not None and not applies(action, on):
        types = [t for t in OBJECT_TYPES if applies(action, t)]
        raise MappingError(f"{where}: {action} never applies to a {on}; it applies to "
                           f"{', '.join(types) or 'no object type'}")
    return Rule(gesture, action, on, state)


def check(mapping: GestureMapping) -> GestureMapping:
    """Returns the mapping if no two rules contradict each other, else raises MappingError."""
    said: dict[tuple, Rule] = {}
    for rule in mapping.rules:
        for context in rule.contexts():
            slot = (rule.gesture, rule.precision, *context)
            other = said.setdefault(slot, rule)
            if other.action != rule.action:
                raise MappingError(f"rules contradict each other: '{other.label}' and "
                                   f"'{rule.label}'; remove one (cbgo mapping unset)")
    return mapping


def parse(data: Any, gestures: Iterable[str]) -> GestureMapping:
    """Returns the mapping in a file's content (None or ``{}``: no rules).

    Raises:
        MappingError: the content is not ``{rules: [...]}`` or a rule is bad (named).
    """
    if data is None:
        return GestureMapping()
    if not isinstance(data, MappingABC):
        raise MappingError(f"expected a map with 'rules', got {type(data).__name__}")
    extra = sorted(set(map(str, data)) - {"rules"})
    if extra:
        raise MappingError(f"unknown field {extra[0]!r}; the file has only 'rules'")
    rules = data.get("rules") or []
    if not isinstance(rules, list):
        raise MappingError(f"rules: expected a list of rules, got {type(rules).__name__}")
    if len(rules) > MAX_RULES:
        raise MappingError(f"rules: {len(rules)} rules; at most {MAX_RULES}")
    gestures = list(gestures)
    return check(GestureMapping(tuple(parse_rule(r, f"rules[{i}]", gestures)
                                      for i, r in enumerate(rules))))


def load(path: Path, gestures: Iterable[str]) -> GestureMapping:
    """Reads a mapping file (a missing file: no rules).

    Raises:
        MappingError: unreadable, not YAML, or a bad rule; the message starts with the path.
    """
    try:
        text = path.read_text()
    except FileNotFoundError:
        return GestureMapping()
    except (OSError, UnicodeDecodeError) as e:
        raise MappingError(f"{path}: cannot read: {e}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise MappingError(f"{path}: not YAML: {' '.join(str(e).split())}") from None
    try:
        return parse(data, gestures)
    except MappingError as e:
        raise MappingError(f"{path}: {e}") from None


def save(path: Path, mapping: GestureMapping) -> None:
    """Writes a mapping file atomically (a watcher never reads half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text("# gesture mapping of this user: see `cbgo mapping --help`\n"
                   + yaml.safe_dump(mapping.to_dict(), sort_keys=False))
    os.replace(tmp, path)


def stamp(path: Path) -> tuple[int, int] | None:
    """Returns (mtime_ns, size) of a file, None if it does not exist (what changes reload)."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size


def apply(tables: Tables, profile: str, mapping: GestureMapping) -> Tables:
    """Returns decision tables whose D4 entries for `profile` follow the mapping.

    In every context a rule covers, the rule's action gets the rule's gesture, and no other
    action of that context keeps that gesture (the gesture's old meaning there is replaced);
    rules are applied from the least precise to the most precise, so the precise ones win.
    """
    d4 = copy.deepcopy(tables.tables["D4"])
    for rule in sorted(mapping.rules, key=lambda r: r.precision):
        for obj_type, bit in rule.contexts():
            entries = d4[str(bit)][profile][obj_type]
            for action, gesture in entries.items():
                if gesture == rule.gesture and action != rule.action:
                    entries[action] = None
            entries[rule.action] = rule.gesture
    return Tables(tables.gestures, tables.users, {**tables.tables, "D4": d4},
                  f"{tables.sha256}+{mapping.key()}")
